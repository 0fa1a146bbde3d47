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
// `--rays RAYS --head_from_helmet POSES [--calibration CAL]`: the markers
// seen by one camera (triangulate's rays.csv, helmet space), taken to head
// space by the stabilize stage's head poses, constrain the solved meshes
// after the blend (blending/ray_constraints.h; docs/method.md, "Constraints
// after the solve"); the calibration, when given, checks the rays' camera
// names. The diagnostics give each ray's distance before and after.
//
// `--weights weights.csv`, `--curves curves.csv`, `--unit_rig FILE.usda`:
// the actor's units fitted to each solved mesh (blending/unit_curves.h;
// docs/method.md, "Animation curves"), written as a per-frame table, as
// per-channel curves and as a USD BlendShape rig with time-sampled weights
// (docs/formats.md, "Unit weights and curves"); the diagnostics give how
// closely the rig driven by them reproduces the solved meshes.
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
#include <cmath>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <unordered_map>
#include <utility>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "apps/command.h"
#include "core/day_markers.h"
#include "blending/lgi_solver.h"
#include "blending/ray_constraints.h"
#include "blending/solve_index_cache.h"
#include "blending/solve_method.h"
#include "blending/temporal_coherence.h"
#include "blending/unit_curves.h"
#include "core/actor.h"
#include "core/actor_cache.h"
#include "core/calibration.h"
#include "core/file_util.h"
#include "core/frame_data.h"
#include "core/logging.h"
#include "core/mesh_sequence.h"
#include "core/obj_io.h"
#include "core/parallel.h"
#include "triangulation/triangulate.h"

namespace hmc {
namespace {

struct SolveCommandOptions {
  std::string method = "robust";  // robust | lgi | blendshape |
                                  // blendshape-bounded | interp | lgi-rbf
  MethodOptions methods;
  SequenceInputOptions input;
  RayConstraintOptions rays;
  DayMarkersOptions day;  // markers: the day's markers (core/day_markers.h)

  void Register(OptionFields* fields) {
    day.Register(fields);
    fields->Add("method", &method,
                "solve method: " + SolveMethodList());
    methods.Register(fields);
    input.Register(fields);
    rays.Register(fields);
  }
  bool Check() const { return methods.Check() && input.Check() && rays.Check(); }
};

struct SolveCommand {
  std::string actor_dir;
  std::string bundles_file;
  std::string jaw_file;
  std::string out;
  std::string diagnostics_file;
  std::string diagnostics_detail = "summary";  // summary | full (docs/formats.md, "Solve diagnostics")
  std::string topology_file;
  std::string rays_file;
  std::string calibration_file;
  std::string poses_file;
  std::string weights_file;
  std::string curves_file;
  std::string unit_rig_file;
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

// A residual as the diagnostics give it: to 0.1 um, which every reader
// (the report's plots, the review page) is far coarser than.
double DiagnosticMm(double mm) { return std::round(mm * 1e4) / 1e4; }

// One frame's record of the diagnostics file: its counts and residuals,
// and per observed bundle its status and residual; with `full`, every
// bundle with the shapes and weights of its answer and lgi's query.
nlohmann::json FrameDiagnostics(const Actor& actor, const FrameSolve& f,
                                const std::vector<std::string>& outliers, bool full) {
  nlohmann::json bundles = nlohmann::json::array();
  int counts[3] = {0, 0, 0};  // inside, projected, filled
  double residual_sum = 0.0, residual_max = 0.0;
  for (size_t k = 0; k < f.bundles.size() && f.ok; ++k) {
    const BundleSolve& b = f.bundles[k];
    if (b.status == BundleSolve::Status::kUnused) continue;
    ++counts[b.status == BundleSolve::Status::kInside      ? 0
             : b.status == BundleSolve::Status::kProjected ? 1
                                                           : 2];
    if (b.Measured()) {
      residual_sum += b.residual;
      residual_max = std::max(residual_max, b.residual);
    }
    if (!full) {
      if (b.Measured()) {
        bundles.push_back({{"marker", actor.markers[k].name},
                           {"status", StatusName(b.status)},
                           {"residual_mm", DiagnosticMm(b.residual)}});
      }
      continue;
    }
    nlohmann::json shapes = nlohmann::json::array();
    nlohmann::json weights = nlohmann::json::array();
    for (const auto& [n, w] : f.Weights(static_cast<int>(k))) {
      shapes.push_back(actor.shapes[n].name);
      weights.push_back(w);
    }
    nlohmann::json entry = {{"marker", actor.markers[k].name},
                            {"status", StatusName(b.status)},
                            {"filled_missing", b.status == BundleSolve::Status::kFilled},
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
  const int measured = counts[0] + counts[1];
  return {{"frame", f.frame},
          {"ok", f.ok},
          {"reason", f.reason},
          {"jaw",
           {{"open_deg", f.jaw.open_deg},
            {"lateral_deg", f.jaw.lateral_deg},
            {"protrude_mm", f.jaw.protrude_mm}}},
          {"unknown_markers", f.unknown_markers},
          {"outlier_markers", outliers},
          {"inside", counts[0]},
          {"projected", counts[1]},
          {"filled", counts[2]},
          {"residual_mean_mm", DiagnosticMm(measured ? residual_sum / measured : 0.0)},
          {"residual_max_mm", DiagnosticMm(residual_max)},
          {"bundles", bundles}};
}

std::vector<MatX3d> ShapeDisplacements(const Actor& actor) {
  std::vector<MatX3d> out;
  for (const Shape& shape : actor.shapes) out.push_back(shape.displacement);
  return out;
}

// rays.csv's rays (helmet space) as constraints in head space: x_head =
// head_from_helmet * x_helmet for the ray's frame. Rays of frames outside
// the sequence or without a head pose, and of markers the actor does not
// have, are left out with a warning each kind.
std::vector<RayConstraint> HeadSpaceRays(const SolveCommand& cmd, const Actor& actor,
                                         const DenseSequence& input) {
  const std::vector<MonoRay> rays = ReadRaysCsv(cmd.rays_file);
  std::map<int, Rigid3> poses;
  for (const PoseFrame& p : ReadPosesCsv(cmd.poses_file)) poses[p.frame] = p.pose;
  if (!cmd.calibration_file.empty()) {
    const HelmetRig rig = ReadCalibration(cmd.calibration_file);
    for (const MonoRay& ray : rays) {
      if (std::none_of(rig.cameras.begin(), rig.cameras.end(),
                       [&](const HelmetCamera& c) { return c.name == ray.camera; })) {
        ThrowInputError(cmd.rays_file, 0, "frame {}, marker {}: camera \"{}\" is not in {}",
                        ray.frame, ray.marker, ray.camera, cmd.calibration_file);
      }
    }
  }
  std::unordered_map<std::string, int> marker_index;
  for (size_t k = 0; k < actor.markers.size(); ++k) {
    marker_index[actor.markers[k].name] = static_cast<int>(k);
  }
  const int num_frames = static_cast<int>(input.frames.size());
  int outside = 0, no_pose = 0, unknown = 0;
  std::vector<RayConstraint> out;
  for (const MonoRay& ray : rays) {
    const int f = ray.frame - input.first_frame;
    const auto marker = marker_index.find(ray.marker);
    const auto pose = poses.find(ray.frame);
    if (f < 0 || f >= num_frames) {
      ++outside;
    } else if (marker == marker_index.end()) {
      ++unknown;
    } else if (pose == poses.end()) {
      ++no_pose;
    } else {
      out.push_back({f, marker->second, ray.camera, pose->second * ray.origin_in_helmet,
                     pose->second.linear() * ray.direction_in_helmet});
    }
  }
  if (outside) spdlog::warn("{}: {} rays of frames outside the bundles' left out", cmd.rays_file, outside);
  if (unknown) spdlog::warn("{}: {} rays of markers the actor does not have left out", cmd.rays_file, unknown);
  if (no_pose) {
    spdlog::warn("{}: {} rays of frames without a pose in {} left out", cmd.rays_file, no_pose,
                 cmd.poses_file);
  }
  return out;
}

// Writes the diagnostics file (docs/formats.md, "Solve diagnostics"): the
// header fields, then the frames streamed one at a time, one per line. As
// one nlohmann::json the document took about 6x its file size in memory
// (4.9 GB peak for 2,000 frames of a small actor, issue 22).
// rays: empty without --rays, else the header's "rays" summary and, per
// frame, the list of its rays.
struct RayDiagnostics {
  nlohmann::json summary;
  std::vector<nlohmann::json> frames;
};

// The unit fit's header entry and per-frame residuals (null without one).
struct UnitDiagnostics {
  nlohmann::json summary;
  std::vector<double> frame_mean_mm;
};

void WriteDiagnostics(const std::filesystem::path& path, const Actor& actor,
                      const std::string& method, const LgiModel* model,
                      const SolveResult& result, const DenseSequence& input,
                      const RayDiagnostics& rays, const UnitDiagnostics& units, bool full) {
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
                                {"detail", full ? "full" : "summary"},
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
                                  {"max_projection_mm", s.max_projection}}},
                                {"rays", rays.summary},
                                {"unit_fit", units.summary}};
  WriteFileAtomic(path, [&](std::ostream& out) {
    out << "{\n";
    for (const auto& [key, value] : head.items()) {
      out << " " << nlohmann::json(key).dump() << ": " << value.dump() << ",\n";
    }
    out << " \"frames\": [";
    for (size_t i = 0; i < result.frames.size(); ++i) {
      nlohmann::json frame = FrameDiagnostics(actor, result.frames[i], input.outliers[i], full);
      if (!rays.frames.empty()) frame["rays"] = rays.frames[i];
      if (!units.frame_mean_mm.empty()) frame["unit_fit_mean_mm"] = units.frame_mean_mm[i];
      out << (i ? ",\n  " : "\n  ") << frame.dump();
    }
    out << "\n ]\n}\n";
  });
}

// The robust solve's temporal steps run only on a take; when robust.take
// auto judged the frames not one, a warning says so and how to decide it
// (issue 46, item 4: a continuous clip judged "not a take" was said only
// in the info log).
void WarnIfNotATake(const SolveCommandOptions& options, const MethodReport& report) {
  if (options.methods.robust.take != "auto") return;
  double take = -1, correlation = 0;
  for (const auto& [name, value] : report.values) {
    if (name == "take") take = value;
    if (name == "take_correlation") correlation = value;
  }
  if (take != 0) return;  // a take, or not a robust solve
  spdlog::warn("solve: the frames were judged not a take (the markers' lag-1 correlation {:.2f} < "
               "{}): the temporal steps (3b, 3c, step 5's averaging) were off; give --robust.take "
               "yes for a continuous recording, no for unrelated frames (docs/method.md, \"Takes\")",
               correlation, kTakeCorrelation);
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
                      {cmd.topology_file, "--topology"},
                      {cmd.weights_file, "--weights"},
                      {cmd.curves_file, "--curves"},
                      {cmd.unit_rig_file, "--unit_rig"}},
                     {{cmd.actor_dir, "--actor"},
                      {cmd.bundles_file, "--bundles"},
                      {cmd.jaw_file, "--jaw"},
                      {cmd.rays_file, "--rays"},
                      {cmd.calibration_file, "--calibration"},
                      {cmd.poses_file, "--head_from_helmet"}});
  if (!cmd.rays_file.empty() && cmd.poses_file.empty()) {
    throw InputError(fmt::format(
        "--rays {}: the rays are in helmet space; --head_from_helmet (the stabilize stage's "
        "head_from_helmet.csv) is needed to place them in head space",
        cmd.rays_file));
  }
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
  const int num_frames = static_cast<int>(input.frames.size());
  auto pose = [&](int f) { return input.jaw.empty() ? JawPose() : input.jaw[f]; };

  // What is done to each mesh after the solve, frame by frame as the solve
  // hands them over (issue 46: a long take's meshes are never all held):
  // the rays' constraints, the units' fit, the write.
  std::vector<RayConstraint> rays;
  std::vector<std::vector<char>> observed;
  std::vector<Mat3> site_motion;
  if (!cmd.rays_file.empty()) {
    rays = HeadSpaceRays(cmd, actor, input);
    // The sewing's weights: the lgi model's (built or loaded for methods
    // that do not use it).
    if (!solvers.lgi_model()) solvers.Prepare("lgi");
    observed.assign(num_frames, std::vector<char>(actor.markers.size(), 0));
    for (int f = 0; f < num_frames; ++f) {
      for (size_t k = 0; k < actor.markers.size(); ++k) {
        observed[f][k] = input.frames[f].bundles.count(actor.markers[k].name) > 0;
      }
    }
    if (cmd.options.rays.depth == "dataset") {
      site_motion = SiteMotionCovariances(ShapeDisplacements(actor), solvers.lgi_model()->data.sites,
                                          actor.neutral.F);
    }
  }
  std::vector<RayResidual> ray_residuals(rays.size());
  std::vector<char> frame_ok(num_frames, 0);
  const bool fit_units =
      !cmd.weights_file.empty() || !cmd.curves_file.empty() || !cmd.unit_rig_file.empty();
  std::optional<UnitRig> unit_rig;
  std::optional<UnitFitter> unit_fitter;
  UnitFit fit;
  if (fit_units) {
    unit_rig.emplace(UnitRigFromActor(actor));
    unit_fitter.emplace(*unit_rig, actor);
    fit.weights.assign(num_frames, Eigen::VectorXd());
    fit.mean_mm.assign(num_frames, 0.0);
  }

  SolveResult result;
  // Solves the sequence, handing each final mesh to emit in frame order, a
  // batch of frames at a time (the units' fit runs over a batch in
  // parallel).
  auto solve = [&](const EmitMesh& emit) {
    constexpr size_t kBatch = 16;
    std::vector<std::pair<int, MatX3d>> batch;
    std::vector<MatX3d*> in_batch(num_frames, nullptr);
    auto flush = [&] {
      for (auto& [f, mesh] : batch) in_batch[f] = &mesh;
      if (!rays.empty()) {
        const std::vector<RayResidual> r = ApplyRayConstraints(
            rays, solvers.lgi_model()->data.sites, actor.neutral.F, solvers.lgi_model()->nn,
            observed, frame_ok, cmd.options.rays, num_frames,
            [&](int f) { return in_batch[f]; }, site_motion);
        for (size_t i = 0; i < rays.size(); ++i) {
          if (in_batch[rays[i].frame_index]) ray_residuals[i] = r[i];
        }
      }
      if (unit_fitter) {
        ParallelFor(0, static_cast<int64_t>(batch.size()), [&](int64_t i) {
          const int f = batch[i].first;
          fit.mean_mm[f] = unit_fitter->Fit(batch[i].second, pose(f), &fit.weights[f]);
        });
      }
      for (auto& [f, mesh] : batch) {
        emit(mesh);
        in_batch[f] = nullptr;
      }
      batch.clear();
    };
    const MeshSink sink = [&](int f, const FrameSolve& frame, const MatX3d& mesh) {
      frame_ok[f] = frame.ok;
      batch.emplace_back(f, mesh);
      if (batch.size() == kBatch) flush();
    };
    result = solvers.Solve(cmd.options.method, input.frames, input.jaw, input.frame_errors, &sink);
    flush();
    // Thrown before the output is renamed into place: nothing written.
    if (result.summary.bad_frames >= static_cast<int>(result.frames.size())) {
      ThrowInputError(cmd.bundles_file, 0,
                      "no frame could be solved (frame {}: {}); nothing written",
                      result.frames.front().frame, result.frames.front().reason);
    }
  };
  if (SequenceFormatStreams(format)) {
    WriteMeshSequenceStreamed(cmd.out, num_frames, static_cast<int>(actor.neutral.V.rows()),
                              input.first_frame, cmd.fps, solve);
  } else {
    MeshSequence seq;
    solve([&](const MatX3d& mesh) { seq.frames.push_back(mesh); });
    seq.start_frame = input.first_frame;
    seq.fps = cmd.fps;
    seq.topology = actor.neutral;
    WriteMeshSequence(cmd.out, seq);
  }

  RayDiagnostics ray_diagnostics;
  if (!cmd.rays_file.empty()) {
    const RayConstraintSummary summary = SummarizeRays(ray_residuals);
    spdlog::info("solve: rays: {}", summary.BriefReport());
    ray_diagnostics.summary = {{"rays", summary.rays},
                               {"applied", summary.applied},
                               {"observed", summary.observed},
                               {"bad_frame", summary.bad_frame},
                               {"behind", summary.behind},
                               {"too_far", summary.too_far},
                               {"mean_before_mm", summary.mean_before_mm},
                               {"max_before_mm", summary.max_before_mm},
                               {"mean_after_mm", summary.mean_after_mm},
                               {"max_after_mm", summary.max_after_mm}};
    ray_diagnostics.frames.assign(num_frames, nlohmann::json::array());
    for (size_t r = 0; r < rays.size(); ++r) {
      ray_diagnostics.frames[rays[r].frame_index].push_back(
          {{"marker", actor.markers[rays[r].marker].name},
           {"camera", rays[r].camera},
           {"status", RayStatusName(ray_residuals[r].status)},
           {"before_mm", ray_residuals[r].before_mm},
           {"after_mm", ray_residuals[r].after_mm}});
    }
  }

  UnitDiagnostics unit_diagnostics;
  if (fit_units) {
    fit.Summarize();
    const UnitAnimation animation =
        MakeUnitAnimation(*unit_rig, actor, fit, input.jaw, input.first_frame, cmd.fps);
    if (!cmd.weights_file.empty()) WriteUnitWeightsCsv(cmd.weights_file, animation);
    if (!cmd.curves_file.empty()) WriteUnitCurvesCsv(cmd.curves_file, animation);
    if (!cmd.unit_rig_file.empty()) {
      WriteUnitRigUsda(cmd.unit_rig_file, *unit_rig, actor, animation, input.jaw);
    }
    spdlog::info("solve: {} units fitted to the solved meshes: the rig driven by the weights is "
                 "{:.4f} mm from them (mean; worst frame {:.4f})",
                 unit_rig->names.size(), fit.mean_mm_all, fit.max_frame_mean_mm);
    unit_diagnostics.summary = {{"units", unit_rig->names.size()},
                                {"mean_mm", fit.mean_mm_all},
                                {"max_frame_mean_mm", fit.max_frame_mean_mm}};
    unit_diagnostics.frame_mean_mm = fit.mean_mm;
  }

  WriteOptionsUsed(binding.fields(), parent / "options_used.yaml", "solve");
  if (!cmd.topology_file.empty()) WriteObj(cmd.topology_file, actor.neutral);
  if (!cmd.diagnostics_file.empty()) {
    WriteDiagnostics(cmd.diagnostics_file, actor, cmd.options.method, solvers.lgi_model(), result,
                     input, ray_diagnostics, unit_diagnostics, cmd.diagnostics_detail == "full");
  }
  WarnIfNotATake(cmd.options, result.report);
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
                  "Per frame diagnostics (JSON): counts, residuals, each observed bundle's status "
                  "and residual");
  app->add_option("--diagnostics_detail", cmd->diagnostics_detail,
                  "summary: per frame and observed bundle its status and residual; full: every "
                  "bundle's shapes and weights too (about 50x larger)")
      ->check(CLI::IsMember({"summary", "full"}));
  app->add_option("--topology", cmd->topology_file,
                  "Also write the meshes' topology (the actor's neutral, mm, with UVs) as "
                  "an OBJ: the mesh a .pc2/.mdd is applied to in Blender (docs/blender.md)");
  app->add_option("--rays", cmd->rays_file,
                  "rays.csv (hmc triangulate): markers seen by one camera, whose surface point the "
                  "solved mesh is then moved onto (docs/method.md, \"Constraints after the solve\")")
      ->check(CLI::ExistingFile);
  app->add_option("--head_from_helmet", cmd->poses_file,
                  "head_from_helmet.csv (hmc stabilize): places the rays in head space")
      ->check(CLI::ExistingFile);
  app->add_option("--calibration", cmd->calibration_file,
                  "The rig's calibration: checks the rays' camera names")
      ->check(CLI::ExistingFile);
  app->add_option("--weights", cmd->weights_file,
                  "weights.csv: per frame, the weights of the actor's units fitted to the solved "
                  "mesh (and the jaw pose; docs/formats.md, \"Unit weights and curves\")");
  app->add_option("--curves", cmd->curves_file,
                  "curves.csv: the same weights as one curve per channel (channel,frame,time_s,value)");
  app->add_option("--unit_rig", cmd->unit_rig_file,
                  "A .usda: the actor's units as a USD BlendShape rig, the weights time-sampled");
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
