// `hmc eval --actor DIR --truth T --recon R [--bundles bundles.csv]
// [--rays rays.csv] [--out DIR] [--frames 1,10,...] [--json]`: how far a reconstruction is
// from the truth, per frame and overall, over the face region and over all
// vertices (core/mesh_metrics.h): mean, RMS, 95th percentile and max vertex
// error, the bundle residual and the detail error. T and R: any mesh-sequence
// format (core/mesh_sequence.h); frames are matched by frame number.
//
// With --out: eval.json, per_frame.csv, error_uv_mean.exr (mean error per
// vertex over the frames, in UV space) and, for the chosen frames,
// error_uv_NNNNNN.exr and frame_NNNNNN.png (truth | reconstruction | error
// heat map with a colour bar), plus options_used.yaml. Formats:
// docs/formats.md, "hmc eval outputs".
#include <fmt/format.h>

#include <memory>
#include <string>
#include <vector>

#include "apps/command.h"
#include "core/actor.h"
#include "core/error.h"
#include "core/file_util.h"
#include "core/logging.h"
#include "eval/run_eval.h"
#include "triangulation/triangulate.h"

namespace hmc {
namespace {

struct EvalCommand {
  std::string actor_dir;
  std::string truth;
  std::string recon;
  std::string bundles;
  std::string rays;
  std::string out;
  std::vector<int> frames;
  bool json = false;
  EvalOptions options;
};

void PrintTable(const EvalOutput& e, int vertices, double face_radius_mm) {
  const SequenceMetrics& metrics = e.metrics;
  fmt::print(
      "hmc eval: {} frames, {} vertices ({} in the face region, "
      "within {} mm of a marker)\n",
      e.frames, vertices, metrics.face_vertices, face_radius_mm);
  fmt::print("{:<14}{:>10}{:>10}{:>10}{:>10}\n", "error (mm)", "mean", "rms",
             "p95", "max");
  auto row = [](const char* name, const ErrorStats& s) {
    fmt::print("{:<14}{:>10.4f}{:>10.4f}{:>10.4f}{:>10.4f}\n", name, s.mean,
               s.rms, s.p95, s.max);
  };
  row("face", metrics.face);
  row("all", metrics.all);
  row("bundle", metrics.bundle);
  fmt::print("detail (mean |dL|, mm): face {:.4f}, all {:.4f}\n",
             metrics.detail_face, metrics.detail_all);
  if (metrics.flicker_all.frames_used > 0) {
    fmt::print(
        "flicker (mean |e(t+1) - 2e(t) + e(t-1)|, mm/frame^2): face {:.4f}, "
        "all {:.4f} ({} frames)\n",
        metrics.flicker_face.mean, metrics.flicker_all.mean,
        metrics.flicker_all.frames_used);
  } else {
    fmt::print("flicker: n/a (fewer than 3 consecutive frames)\n");
  }
}

int Run(EvalCommand& cmd, OptionBinding& binding) {
  binding.Apply();
  RequireValid(cmd.options, "eval");
  PrepareOutputPaths({{cmd.out, "--out", true}},
                     {{cmd.actor_dir, "--actor"}, {cmd.truth, "--truth"}, {cmd.recon, "--recon"},
                      {cmd.bundles, "--bundles"}, {cmd.rays, "--rays"}});
  const Actor actor = LoadActor(cmd.actor_dir);
  EvalInput input;
  input.actor = &actor;
  input.truth = cmd.truth;
  input.recon = cmd.recon;
  input.bundles = cmd.bundles;
  if (!cmd.rays.empty()) {
    for (const MonoRay& ray : ReadRaysCsv(cmd.rays)) input.at_markers.push_back({ray.frame, ray.marker});
    input.at_markers_file = cmd.rays;
  }
  EvalOutput output;
  if (cmd.out.empty()) {
    output = RunEval(input, cmd.options);
  } else {
    // Written whole: the error maps of an earlier run's --frames do not
    // stay beside this run's (docs/reliability.md).
    WriteFolderAtomic(cmd.out, "hmc eval", [&](const std::filesystem::path& dir) {
      input.out = dir;
      input.picture_frames = cmd.frames;
      output = RunEval(input, cmd.options);
      WriteOptionsUsed(binding.fields(), dir / "options_used.yaml", "eval");
    });
  }
  if (cmd.json) {
    fmt::print("{}\n", output.report.dump());
  } else {
    PrintTable(output, actor.NumVertices(),
               cmd.options.metrics.face_radius_mm);
    if (output.report.contains("at_markers")) {
      const nlohmann::json& m = output.report["at_markers"];
      fmt::print(
          "at the {} marker-frames of {} ({} frames): mean {:.4f} mm, max {:.4f}; face within "
          "{} mm of them {:.4f}, away {:.4f}; other markers {:.4f}\n",
          m["marker_frames"].get<int>(), cmd.rays, m["frames"].get<int>(),
          m["mean_mm"].get<double>(), m["max_mm"].get<double>(), m["radius_mm"].get<double>(),
          m["near_mean_mm"].get<double>(), m["away_mean_mm"].get<double>(),
          m["other_markers_mean_mm"].get<double>());
    }
  }
  spdlog::info("eval: {}", output.BriefReport());
  return 0;
}

}  // namespace

HMC_COMMAND(Eval, "", "eval",
            "Compare a reconstructed mesh sequence with the truth") {
  auto cmd = std::make_shared<EvalCommand>();
  app->add_option("--actor", cmd->actor_dir, "Actor package folder")
      ->required()
      ->check(CLI::ExistingDirectory);
  app->add_option("--truth", cmd->truth,
                  "Ground-truth mesh sequence (.pc2, .mdd, .usda, OBJ folder)")
      ->required()
      ->check(CLI::ExistingPath);
  app->add_option("--recon", cmd->recon, "Reconstructed mesh sequence")
      ->required()
      ->check(CLI::ExistingPath);
  app->add_option("--bundles", cmd->bundles,
                  "bundles.csv: measure the bundle residual against these "
                  "instead of the truth's marker points")
      ->check(CLI::ExistingFile);
  app->add_option("--rays", cmd->rays,
                  "rays.csv (hmc triangulate): also the error at the markers seen by one camera, "
                  "and near and away from them in their frames (\"at_markers\" in the JSON)")
      ->check(CLI::ExistingFile);
  app->add_option("--out", cmd->out,
                  "Folder for eval.json, per_frame.csv, UV error maps (EXR) "
                  "and pictures (PNG)");
  app->add_option("--frames", cmd->frames,
                  "Frames to picture, comma separated (default: four spread "
                  "over the sequence)")
      ->delimiter(',');
  app->add_flag("--json", cmd->json,
                "Print one JSON object instead of a table");
  auto binding = BindOptions(app, &cmd->options);
  return [cmd, binding] { return Run(*cmd, *binding); };
}

}  // namespace hmc
