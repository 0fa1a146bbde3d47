// `hmc solve --actor DIR --bundles bundles.csv [--jaw jaw.csv] --out OUT
// [--method NAME] [--diagnostics FILE.json] [--topology FILE.obj]`: meshes from bundles. The
// default method `robust` (blending/robust_solver.h, docs/method.md) uses
// local geometric indexing per bundle and frame, sewn with natural-neighbour
// weights (docs/ARCHITECTURE.md, "Method steps"), where the local data explain the markers
// beyond their noise, and a noise-aware global fit elsewhere; `lgi` is the
// paper's method alone; the others (blendshape, blendshape-bounded, interp,
// lgi-rbf: docs/baselines.md) take the same inputs and write the same
// outputs (blending/solve_method.h). OUT
// by extension: .pc2, .mdd, .usda, or a folder of OBJ frames. The lgi index
// is loaded from the package's or the user's cache when valid, else built
// and written to the user cache (blending/solve_index_cache.h): the solve
// never writes into the actor package.
// Writes options_used.yaml (with the method) next to OUT.
//
// Frames run from the first to the last frame number of bundles.csv (a gap
// of more than input.max_frame_gap missing frames is an input error); a
// frame without rows, with too few bundles, without a jaw pose (when --jaw
// is given) or with one out of range is flagged bad in the diagnostics and
// repeats the previous good mesh (the jaw-skinned neutral before the first
// good frame); when no frame can be solved nothing is written and the exit
// code is 2. A bundle outside the actor's reach is an outlier: flagged in
// the diagnostics, dropped from its frame. Unknown marker names are
// ignored with one warning (docs/reliability.md).
#include <algorithm>
#include <memory>
#include <string>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "apps/command.h"
#include "core/day_markers.h"
#include "blending/lgi_solver.h"
#include "blending/solve_index_cache.h"
#include "blending/solve_method.h"
#include "core/actor.h"
#include "core/actor_cache.h"
#include "core/file_util.h"
#include "core/frame_data.h"
#include "core/logging.h"
#include "core/mesh_sequence.h"
#include "core/obj_io.h"

namespace hmc {
namespace {

struct SolveCommandOptions {
  std::string method = "robust";  // robust | lgi | blendshape |
                                  // blendshape-bounded | interp | lgi-rbf
  MethodOptions methods;
  SequenceInputOptions input;
  DayMarkersOptions day;  // markers: the day's markers (core/day_markers.h)

  void Register(OptionFields* fields) {
    day.Register(fields);
    fields->Add("method", &method,
                "solve method: " + SolveMethodList());
    methods.Register(fields);
    input.Register(fields);
  }
  bool Check() const { return methods.Check() && input.Check(); }
};

struct SolveCommand {
  std::string actor_dir;
  std::string bundles_file;
  std::string jaw_file;
  std::string out;
  std::string diagnostics_file;
  std::string topology_file;
  bool no_cache_write = false;
  double fps = 30.0;
  SolveCommandOptions options;
};

const char* StatusName(BundleSolve::Status status) {
  switch (status) {
    case BundleSolve::Status::kInside: return "inside";
    case BundleSolve::Status::kProjected: return "projected";
    case BundleSolve::Status::kFilled: return "filled";
    case BundleSolve::Status::kUnused: return "unused";
  }
  return "unused";
}

// One frame's record of the diagnostics file.
nlohmann::json FrameDiagnostics(const Actor& actor, const FrameSolve& f,
                                const std::vector<std::string>& outliers) {
    nlohmann::json bundles = nlohmann::json::array();
    for (size_t k = 0; k < f.bundles.size() && f.ok; ++k) {
      const BundleSolve& b = f.bundles[k];
      nlohmann::json shapes = nlohmann::json::array();
      nlohmann::json weights = nlohmann::json::array();
      for (const auto& [n, w] : f.Weights(static_cast<int>(k))) {
        shapes.push_back(actor.shapes[n].name);
        weights.push_back(w);
      }
      nlohmann::json entry = {{"marker", actor.markers[k].name},
                              {"status", StatusName(b.status)},
                              {"filled_missing",
                               b.status == BundleSolve::Status::kFilled},
                              {"shapes", shapes},
                              {"weights", weights}};
      if (b.status != BundleSolve::Status::kFilled) {
        entry["projected_mm"] = b.distance;
        entry["candidates"] = b.num_candidates;
        entry["neighbour_cost_mm2"] = b.cost;
        entry["residual_mm"] = b.residual;
      }
      bundles.push_back(entry);
    }
  return {{"frame", f.frame},
          {"ok", f.ok},
          {"reason", f.reason},
          {"jaw",
           {{"open_deg", f.jaw.open_deg},
            {"lateral_deg", f.jaw.lateral_deg},
            {"protrude_mm", f.jaw.protrude_mm}}},
          {"unknown_markers", f.unknown_markers},
          {"outlier_markers", outliers},
          {"bundles", bundles}};
}

// Writes the diagnostics file (docs/formats.md, "Solve diagnostics"): the
// header fields, then the frames streamed one at a time, one per line. As
// one nlohmann::json the document took about 6x its file size in memory
// (4.9 GB peak for 2,000 frames of a small actor, issue 22).
void WriteDiagnostics(const std::filesystem::path& path, const Actor& actor,
                      const std::string& method, const LgiModel* model,
                      const SolveResult& result, const DenseSequence& input) {
  const SolveSummary& s = result.summary;
  nlohmann::json index = nullptr;
  if (model) {
    index = {{"from_cache", model->from_cache},
             {"build_seconds", model->build_seconds}};
  }
  nlohmann::json report = nlohmann::json::object();
  for (const auto& [name, value] : result.report.values) report[name] = value;
  if (!result.report.brief.empty()) report["brief"] = result.report.brief;
  const nlohmann::json head = {{"actor", actor.name},
                                {"method", method},
                                {"index", index},
                                {"report", report},
                                {"summary",
                                 {{"frames", s.frames},
                                  {"bad_frames", s.bad_frames},
                                  {"bundles_inside", s.bundles_inside},
                                  {"bundles_projected", s.bundles_projected},
                                  {"bundles_filled", s.bundles_filled},
                                  {"outlier_bundles", input.num_outliers},
                                  {"unknown_marker_rows", input.unknown_rows},
                                  {"max_projection_mm", s.max_projection}}}};
  WriteFileAtomic(path, [&](std::ostream& out) {
    out << "{\n";
    for (const auto& [key, value] : head.items()) {
      out << " " << nlohmann::json(key).dump() << ": " << value.dump() << ",\n";
    }
    out << " \"frames\": [";
    for (size_t i = 0; i < result.frames.size(); ++i) {
      out << (i ? ",\n  " : "\n  ")
          << FrameDiagnostics(actor, result.frames[i], input.outliers[i]).dump();
    }
    out << "\n ]\n}\n";
  });
}

int Run(SolveCommand& cmd, OptionBinding& binding) {
  binding.Apply();
  RequireValid(cmd.options, "solve");
  CheckSolveMethod(cmd.options.method, "--method");
  // Every output path is checked (and its folder created) before the
  // long work, so a bad one never costs a solve nor replaces a file.
  const SequenceFormat format = SequenceFormatFromPath(cmd.out);
  const std::filesystem::path out_path(cmd.out);
  const std::filesystem::path parent =
      out_path.has_parent_path() ? out_path.parent_path()
                                 : std::filesystem::path(".");
  PrepareOutputPaths({{cmd.out, "--out", format == SequenceFormat::kObjFolder},
                      SideFile(parent / "options_used.yaml", "solve"),
                      {cmd.diagnostics_file, "--diagnostics"},
                      {cmd.topology_file, "--topology"}},
                     {{cmd.actor_dir, "--actor"},
                      {cmd.bundles_file, "--bundles"},
                      {cmd.jaw_file, "--jaw"}});
  const std::shared_ptr<const Actor> loaded = LoadActorForDay(cmd.actor_dir, cmd.options.day.markers);
  const Actor& actor = *loaded;
  // The file's rows (a map per frame) live only until the dense sequence
  // is made: a long shot does not hold them through the solve.
  DenseSequence input = [&] {
    const std::vector<BundleFrame> rows = ReadBundlesCsv(cmd.bundles_file);
    if (rows.empty()) {
      ThrowInputError(cmd.bundles_file, 0, "no frames in the bundles file");
    }
    std::vector<JawFrame> jaw_rows;
    if (!cmd.jaw_file.empty()) {
      jaw_rows = ReadJawCsv(cmd.jaw_file);
    } else if (actor.jaw_rig) {
      spdlog::warn("no --jaw given: solving with the zero jaw pose");
    }
    return MakeDenseSequence(rows, cmd.bundles_file,
                             cmd.jaw_file.empty() ? nullptr : &jaw_rows,
                             cmd.jaw_file, actor, cmd.options.input);
  }();
  // A sequence with no frame to solve is an input error, not an output of
  // repeated neutrals.
  if (std::all_of(input.frame_errors.begin(), input.frame_errors.end(),
                  [](const std::string& e) { return !e.empty(); })) {
    ThrowInputError(cmd.jaw_file.empty() ? cmd.bundles_file : cmd.jaw_file, 0,
                    "no frame can be solved (frame {}: {})", input.first_frame,
                    input.frame_errors.front());
  }

  StageTimer timer("solve " + cmd.options.method);
  MethodSolvers solvers(actor, cmd.options.methods,
                        cmd.no_cache_write ? IndexCacheWrite::kNone
                                           : IndexCacheWrite::kUserCache);
  solvers.Prepare(cmd.options.method);
  DropBundlesBeyondReach(solvers.data(), cmd.options.input.outlier_margin_mm,
                         cmd.bundles_file, &input);
  SolveResult result =
      solvers.Solve(cmd.options.method, input.frames, input.jaw,
                    input.frame_errors);
  if (result.summary.bad_frames >= static_cast<int>(result.frames.size())) {
    ThrowInputError(cmd.bundles_file, 0,
                    "no frame could be solved (frame {}: {}); nothing written",
                    result.frames.front().frame, result.frames.front().reason);
  }

  MeshSequence seq;
  seq.frames = std::move(result.meshes);
  seq.start_frame = input.first_frame;
  seq.fps = cmd.fps;
  seq.topology = actor.neutral;
  WriteMeshSequence(cmd.out, seq);
  WriteOptionsUsed(binding.fields(), parent / "options_used.yaml", "solve");
  if (!cmd.topology_file.empty()) WriteObj(cmd.topology_file, actor.neutral);
  if (!cmd.diagnostics_file.empty()) {
    WriteDiagnostics(cmd.diagnostics_file, actor, cmd.options.method, solvers.lgi_model(), result,
                     input);
  }
  spdlog::info("solve ({}): {}", cmd.options.method,
               result.summary.BriefReport());
  return 0;
}

}  // namespace

HMC_COMMAND(Solve, "", "solve",
            "Solve meshes from bundles (default: local geometric indexing "
            "with a noise-aware global fit; other methods: --method)") {
  auto cmd = std::make_shared<SolveCommand>();
  app->add_option("--actor", cmd->actor_dir, "Actor package folder")
      ->required()
      ->check(CLI::ExistingDirectory);
  app->add_option("--bundles", cmd->bundles_file,
                  "bundles.csv (frame,marker,x,y,z in head space, mm)")
      ->required()
      ->check(CLI::ExistingFile);
  app->add_option("--jaw", cmd->jaw_file, "jaw.csv: the jaw pose per frame")
      ->check(CLI::ExistingFile);
  app->add_option("--out", cmd->out,
                  "Output mesh sequence: .pc2, .mdd, .usda or a folder of OBJ "
                  "frames")
      ->required();
  app->add_option("--diagnostics", cmd->diagnostics_file,
                  "Per frame and bundle diagnostics (JSON)");
  app->add_option("--topology", cmd->topology_file,
                  "Also write the meshes' topology (the actor's neutral, mm, with UVs) as "
                  "an OBJ: the mesh a .pc2/.mdd is applied to in Blender (docs/blender.md)");
  app->add_option("--fps", cmd->fps, "Frame rate written to the output")
      ->check(CLI::PositiveNumber);
  app->add_flag("--no_cache_write", cmd->no_cache_write,
                "Keep a built index in memory only (default: write it to "
                "the user cache, $XDG_CACHE_HOME/hmc; the actor package is "
                "never written)");
  auto binding = BindOptions(app, &cmd->options);
  return [cmd, binding] { return Run(*cmd, *binding); };
}

}  // namespace hmc
