#include "eval/experiment.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "core/actor.h"
#include "core/color_map.h"
#include "core/error.h"
#include "core/file_util.h"
#include "core/frame_data.h"
#include "core/image_io.h"
#include "core/logging.h"
#include "core/mesh_sequence.h"
#include "eval/error_pictures.h"
#include "synth/face_model.h"
#include "synth/synth_actor.h"
#include "synth/truth_frames.h"

namespace hmc {
namespace {

// Parses a number; false if `text` is not entirely one.
bool ParseDouble(const std::string& text, double* value) {
  try {
    size_t used = 0;
    *value = std::stod(text, &used);
    return used == text.size() && std::isfinite(*value);
  } catch (const std::exception&) {
    return false;
  }
}

}  // namespace

void ExperimentOptions::Register(OptionFields* fields) {
  fields->Add("kinds", &kinds,
              "material kinds, comma separated")
      .OneOf(TruthFrameKinds());
  fields->Add("noise_mm", &noise_mm,
              "marker noise levels (std per coordinate, mm), comma "
              "separated")
      .In(0, 50);
  fields->Add("methods", &methods,
              "solve methods, comma separated")
      .OneOf(SolveMethodNames());
  fields->Add("default_frames", &default_frames,
              "frames of a kind not listed in `frames`")
      .In(1, 100000);
  fields->Add("frames", &frames,
              "frames per kind, kind:count comma separated (dataset: all "
              "shapes)");
  fields->Add("fps", &fps, "frame rate of the material (frames/s)").Above(0).AtMost(1000);
  fields->Add("write_meshes", &write_meshes,
              "write truth.pc2 and <method>.pc2 per material");
  fields->Add("picture_kind", &picture_kind,
              "material pictured (first noise level)");
  fields->Add("picture_frame", &picture_frame, "frame number pictured");
  picture.Register(fields);
  metrics.Register(fields);
  solve.Register(fields);
}


bool ExperimentOptions::Check() const {
  if (!metrics.Check() || !solve.Check() || !picture.Check()) return false;
  CHECK_OPTION_LIMITS();
  CHECK_OPTION(!kinds.empty());
  CHECK_OPTION(!noise_mm.empty());
  CHECK_OPTION(!methods.empty());
  for (const std::string& entry : frames) {
    const size_t colon = entry.find(':');
    double v = 0;
    if (colon == std::string::npos ||
        !ParseDouble(entry.substr(colon + 1), &v) || v < 1 || v > 100000 ||
        v != std::floor(v)) {
      spdlog::error("invalid option: frames entry '{}' is not kind:count",
                    entry);
      return false;
    }
  }
  return true;
}

int ExperimentOptions::FramesOf(const std::string& kind) const {
  for (const std::string& entry : frames) {
    const size_t colon = entry.find(':');
    if (entry.substr(0, colon) == kind) {
      return std::stoi(entry.substr(colon + 1));
    }
  }
  return default_frames;
}

std::string ExperimentOutput::BriefReport() const {
  return fmt::format("{} rows in {:.1f} s", rows.size(), seconds);
}

namespace {

std::string NoiseLabel(double noise_mm) { return fmt::format("{:g}", noise_mm); }

// Rounds to float32, as mesh-sequence files store positions.
MatX3d AsStored(const MatX3d& x) { return x.cast<float>().cast<double>(); }

void WritePicture(const std::filesystem::path& path, const TriMesh& neutral,
                  const MatX3d& truth, const MatX3d& recon, int number,
                  const std::string& method, double hi, ColorMap color_map,
                  const ExperimentOptions& o) {
  const Eigen::VectorXd err = VertexErrors(truth, recon);
  WritePng(path, ErrorPicture(neutral, truth, recon, err,
                              {fmt::format("truth {}", number), method,
                               fmt::format("error, mean {:.3f} mm",
                                           err.mean())},
                              hi, color_map, o.picture));
}

std::string ResultsMarkdown(const std::string& actor_name, int seed,
                            const std::vector<ExperimentRow>& rows, double seconds) {
  std::string md = fmt::format(
      "# hmc experiment: {} (seed {})\n\n"
      "Errors in mm over the face region (vertices within face_radius_mm of "
      "a marker) and over all vertices, pooled over every frame and vertex "
      "(docs/formats.md, \"hmc eval outputs\"). detail: mean |L truth - L "
      "recon| over the face (uniform Laplacian). bundle: mean residual at "
      "the input bundles. flicker: mean |e(t+1) - 2e(t) + e(t-1)| over the "
      "face (mm/frame^2; n/a for the dataset, whose frames are not a "
      "sequence). ms/frame: wall time of the sequence solve / frames. "
      "local: share of the observed bundles (all frames) that took the "
      "local (lgi) answer; local gain: how much lower robust's face mean "
      "is than robust-global's (robust without the local data) on the same "
      "material, in % of robust-global's. take: the lag-1 correlation of "
      "the markers, and whether robust treated the frames as a take (>= "
      "0.5: the steps that average in time run).\n\n",
      actor_name, seed);
  md +=
      "| material | noise (mm) | method | face mean | face rms | face p95 | "
      "face max | all mean | detail | bundle | flicker | local | local gain "
      "| take | ms/frame | bad |\n"
      "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const ExperimentRow& r : rows) {
    const SequenceMetrics& m = r.metrics;
    const std::string local =
        r.local_share < 0 ? "" : fmt::format("{:.0f} %", 100 * r.local_share);
    std::string gain;
    if (r.method == "robust") {
      for (const ExperimentRow& g : rows) {
        if (g.method == "robust-global" && g.material == r.material &&
            g.metrics.face.mean > 0) {
          gain = fmt::format(
              "{:+.1f} %",
              100 * (g.metrics.face.mean - m.face.mean) / g.metrics.face.mean);
        }
      }
    }
    const std::string flicker =
        r.kind == "dataset" || m.flicker_face.frames_used == 0
            ? "n/a"
            : fmt::format("{:.4f}", m.flicker_face.mean);
    const std::string take =
        r.take_correlation < -1
            ? ""
            : fmt::format("{:.2f} {}", r.take_correlation, r.take ? "yes" : "no");
    md += fmt::format(
        "| {} | {} | {} | {:.4f} | {:.4f} | {:.4f} | {:.3f} | {:.4f} | "
        "{:.5f} | {:.2e} | {} | {} | {} | {} | {:.1f} | {} |\n",
        r.kind, NoiseLabel(r.noise_mm), r.method, m.face.mean, m.face.rms,
        m.face.p95, m.face.max, m.all.mean, m.detail_face, m.bundle.mean,
        flicker, local, gain, take, r.solve_ms_per_frame, r.bad_frames);
  }
  md += fmt::format("\nTotal time: {:.1f} s.\n", seconds);
  return md;
}

}  // namespace

ExperimentOutput RunExperiment(const ExperimentInput& input,
                               const ExperimentOptions& o) {
  RequireValid(o, "experiment");
  const ColorMap color_map = ParseColorMap(o.picture.color_map);
  const auto start = std::chrono::steady_clock::now();
  StageTimer total("experiment");

  const SynthPackage package = LoadSynthPackage(input.actor_dir);
  const Actor& actor = package.actor;
  const FaceModel& model = *package.model;
  const std::vector<DatasetEntry> plan = PlanDataset(model, package.options);
  const std::vector<int> held =
      HeldOutUnits(model, package.options, package.synth_file);

  std::vector<std::string> kinds;
  for (const std::string& kind : o.kinds) {
    if (KindNeedsHeldOutUnits(kind) && held.empty()) {
      spdlog::warn(
          "experiment: skipping kind {}: the actor holds no units out "
          "(make one with `hmc actor synth --holdout N`)",
          kind);
      continue;
    }
    if (kind == "dataset" || KindNeedsHeldOutUnits(kind)) {
      for (const DatasetEntry& entry : plan) {
        if (actor.FindShape(entry.name) < 0) {
          ThrowInputError(actor.dir / "actor.yaml", 0,
                          "the package has no shape '{}' that synth.yaml's "
                          "generator makes: the package was edited or is "
                          "stale",
                          entry.name);
        }
      }
    }
    kinds.push_back(kind);
  }
  const std::vector<double>& noises = o.noise_mm;
  const std::vector<std::string>& methods = o.methods;

  const std::filesystem::path& out = input.out;
  EnsureDirectory(out);
  EnsureDirectory(out / "images");

  MethodSolvers solvers(actor, o.solve, IndexCacheWrite::kUserCache);
  nlohmann::json precompute = nlohmann::json::object();
  for (const std::string& method : methods) {
    const auto t0 = std::chrono::steady_clock::now();
    solvers.Prepare(method);
    precompute[method] =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0)
            .count();
  }
  const SequenceEvaluator evaluator(actor, o.metrics);

  ExperimentOutput output;
  std::vector<ExperimentRow>& rows = output.rows;
  const int total_runs =
      static_cast<int>(kinds.size() * noises.size() * methods.size());
  int run = 0;
  for (const std::string& kind : kinds) {
    for (size_t noise_index = 0; noise_index < noises.size(); ++noise_index) {
      const double noise = noises[noise_index];
      const std::string material = fmt::format("{}_n{}", kind, NoiseLabel(noise));
      TruthFramesOptions to;
      to.kind = kind;
      to.frames = o.FramesOf(kind);
      to.seed = input.seed;
      to.noise_mm = noise;
      to.fps = o.fps;
      RequireValid(to, "experiment material");
      TruthFrames truth;
      {
        StageTimer timer("material " + material);
        truth = MakeTruthFrames(model, actor.markers, plan, to);
      }
      const int F = static_cast<int>(truth.positions.size());
      const std::filesystem::path dir = out / material;
      EnsureDirectory(dir);
      // Through the files, as `hmc solve` would read them.
      WriteBundlesCsv(dir / "bundles.csv", truth.bundles);
      WriteJawCsv(dir / "jaw.csv", truth.jaw);
      WriteFileAtomic(dir / "labels.csv", [&](std::ostream& s) {
        s << "frame,label\n";
        for (int f = 0; f < F; ++f) {
          s << truth.start_frame + f << ',' << truth.labels[f] << '\n';
        }
      });
      const std::vector<BundleFrame> bundles =
          ReadBundlesCsv(dir / "bundles.csv");
      std::vector<JawPose> jaw;
      for (const JawFrame& j : ReadJawCsv(dir / "jaw.csv")) jaw.push_back(j.pose);
      HMC_CHECK(static_cast<int>(bundles.size()) == F);
      HMC_CHECK(static_cast<int>(jaw.size()) == F);
      std::vector<MatX3d> truth_meshes(F);
      std::vector<int> numbers(F);
      for (int f = 0; f < F; ++f) {
        truth_meshes[f] = AsStored(truth.positions[f]);
        numbers[f] = truth.start_frame + f;
      }
      truth.positions.clear();
      MeshSequence seq;
      seq.start_frame = truth.start_frame;
      seq.fps = o.fps;
      seq.topology = actor.neutral;
      if (o.write_meshes) {
        seq.frames = truth_meshes;
        WriteMeshSequence(dir / "truth.pc2", seq);
      }
      const bool picture = kind == o.picture_kind && noise_index == 0 &&
                           o.picture_frame >= truth.start_frame &&
                           o.picture_frame < truth.start_frame + F;
      std::map<std::string, MatX3d> picture_meshes;
      for (const std::string& method : methods) {
        ++run;
        const auto t0 = std::chrono::steady_clock::now();
        SolveResult result = solvers.Solve(method, bundles, jaw);
        // lgi-rbf reuses the lgi choices of the same material: count their
        // time too, so its ms/frame is that of a solve on its own.
        const double seconds =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - t0)
                .count() +
            solvers.last_reused_seconds();
        for (MatX3d& x : result.meshes) x = AsStored(x);
        ExperimentRow row;
        row.kind = kind;
        row.noise_mm = noise;
        row.material = material;
        row.method = method;
        row.frames = F;
        row.bad_frames = result.summary.bad_frames;
        row.solve_ms_per_frame = 1000.0 * seconds / std::max(F, 1);
        {
          double local = -1, global = -1;
          for (const auto& [name, value] : result.report.values) {
            if (name == "bundles_local") local = value;
            if (name == "bundles_global") global = value;
            if (name == "take_correlation") row.take_correlation = value;
            if (name == "take") row.take = value != 0;
          }
          if (local >= 0 && global >= 0 && local + global > 0) {
            row.local_share = local / (local + global);
          }
        }
        row.metrics =
            evaluator.Evaluate(truth_meshes, result.meshes, numbers, &bundles);
        row.metrics.per_frame.clear();
        spdlog::info(
            "experiment [{}/{}] {} {}: face mean {:.4f} mm, p95 {:.4f} mm, "
            "{:.1f} ms/frame",
            run, total_runs, material, method, row.metrics.face.mean,
            row.metrics.face.p95, row.solve_ms_per_frame);
        if (picture) {
          picture_meshes[method] =
              result.meshes[o.picture_frame - truth.start_frame];
        }
        if (o.write_meshes) {
          seq.frames = std::move(result.meshes);
          WriteMeshSequence(dir / (method + ".pc2"), seq);
        }
        rows.push_back(std::move(row));
      }
      if (picture) {
        const MatX3d& t = truth_meshes[o.picture_frame - truth.start_frame];
        double hi = o.picture.heat_max_mm;
        if (hi <= 0) {
          for (const auto& [method, r] : picture_meshes) {
            std::vector<double> face =
                Select(VertexErrors(t, r), evaluator.face_mask());
            hi = std::max(hi, ComputeErrorStats(&face).p95);
          }
          if (hi <= 0) hi = 1e-3;
        }
        for (const auto& [method, r] : picture_meshes) {
          WritePicture(out / "images" /
                           fmt::format("{}_frame{:06d}_{}.png", material,
                                       o.picture_frame, method),
                       actor.neutral, t, r, o.picture_frame, method, hi,
                       color_map, o);
        }
      }
    }
  }

  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start)
          .count();
  nlohmann::json table = nlohmann::json::array();
  for (const ExperimentRow& r : rows) {
    const SequenceMetrics& m = r.metrics;
    table.push_back(
        {{"material", r.material},
         {"kind", r.kind},
         {"noise_mm", r.noise_mm},
         {"method", r.method},
         {"frames", r.frames},
         {"bad_frames", r.bad_frames},
         {"solve_ms_per_frame", r.solve_ms_per_frame}});
    if (r.local_share >= 0) table.back()["local_share"] = r.local_share;
    if (r.take_correlation >= -1) {
      table.back()["take_correlation"] = r.take_correlation;
      table.back()["take"] = r.take;
    }
    table.back().update(PooledMetricsJson(m));
  }
  const nlohmann::json report = {
      {"actor", actor.name},
      {"actor_dir", input.actor_dir.string()},
      {"seed", input.seed},
      {"vertices", actor.NumVertices()},
      {"shapes", actor.shapes.size()},
      {"markers", actor.markers.size()},
      {"face_region",
       {{"radius_mm", o.metrics.face_radius_mm},
        {"vertices", rows.empty() ? 0 : rows.front().metrics.face_vertices}}},
      {"bundle_targets", "the material's bundles.csv"},
      {"precompute_seconds", precompute},
      {"total_seconds", seconds},
      {"rows", table}};
  WriteFileAtomic(out / "results.json", report.dump(1) + "\n");
  WriteFileAtomic(out / "results.md",
                  ResultsMarkdown(actor.name, input.seed, rows, seconds));
  output.seconds = seconds;
  return output;
}

}  // namespace hmc
