#include "eval/run_eval.h"

#include <algorithm>
#include <map>

#include <fmt/format.h>

#include "core/color_map.h"
#include "core/error.h"
#include "core/file_util.h"
#include "core/frame_data.h"
#include "core/image_io.h"
#include "core/logging.h"
#include "eval/error_pictures.h"

namespace hmc {

void EvalOptions::Register(OptionFields* fields) {
  metrics.Register(fields);
  fields->Add("uv_resolution", &uv_resolution,
              "side of the UV-space error maps (px)")
      .In(8, 8192);
  fields->Add("markers_radius_mm", &markers_radius_mm,
              "with --rays: the face's vertices within this of a listed marker are \"near\" it, "
              "the others \"away\" (mm)")
      .In(0, 1000);
  picture.Register(fields);
}

bool EvalOptions::Check() const {
  CHECK_OPTION_LIMITS();
  return metrics.Check() && picture.Check();
}

FrameMatch MatchFrames(const MeshSequence& a, const MeshSequence& b) {
  FrameMatch m;
  for (size_t i = 0; i < a.frames.size(); ++i) {
    const int number = a.start_frame + static_cast<int>(i);
    const int j = number - b.start_frame;
    if (j >= 0 && j < static_cast<int>(b.frames.size())) {
      m.pairs.emplace_back(static_cast<int>(i), j);
      m.numbers.push_back(number);
    }
  }
  return m;
}

std::string EvalOutput::BriefReport() const {
  return fmt::format("{} frames, face mean {:.4f} mm, all mean {:.4f} mm",
                     frames, metrics.face.mean, metrics.all.mean);
}

namespace {

void WritePerFrameCsv(const std::filesystem::path& path,
                      const std::vector<FrameMetrics>& evals) {
  std::string csv =
      "frame,face_mean_mm,face_rms_mm,face_p95_mm,face_max_mm,all_mean_mm,"
      "all_rms_mm,all_p95_mm,all_max_mm,bundle_mean_mm,bundle_max_mm,"
      "detail_face_mm,detail_all_mm\n";
  for (const FrameMetrics& e : evals) {
    csv += fmt::format(
        "{},{:.6g},{:.6g},{:.6g},{:.6g},{:.6g},{:.6g},{:.6g},"
        "{:.6g},{:.6g},{:.6g},{:.6g},{:.6g}\n",
        e.frame, e.face.mean, e.face.rms, e.face.p95, e.face.max, e.all.mean,
        e.all.rms, e.all.p95, e.all.max, e.bundle.mean, e.bundle.max,
        e.detail_face, e.detail_all);
  }
  WriteFileAtomic(path, csv);
}

// The error at listed (frame, marker) pairs and around them (EvalInput::
// at_markers): per matched frame that lists any, the listed markers'
// surface points, the face's vertices within `radius` (on the neutral) of
// one of them ("near") and the other face vertices ("away"), and the other
// markers' surface points. Pairs of frames not in both sequences or of
// markers the actor does not have are counted as skipped.
nlohmann::json AtMarkersJson(const Actor& actor, const std::vector<MatX3d>& truth,
                             const std::vector<MatX3d>& recon, const std::vector<int>& numbers,
                             const std::vector<uint8_t>& face,
                             const std::vector<std::pair<int, std::string>>& pairs,
                             double radius) {
  std::map<std::string, int> marker_index;
  for (size_t k = 0; k < actor.markers.size(); ++k) marker_index[actor.markers[k].name] = k;
  std::map<int, std::vector<int>> listed;  // frame index -> markers
  int skipped = 0;
  for (const auto& [number, name] : pairs) {
    const auto f = std::find(numbers.begin(), numbers.end(), number);
    const auto k = marker_index.find(name);
    if (f == numbers.end() || k == marker_index.end()) {
      ++skipped;
      continue;
    }
    listed[static_cast<int>(f - numbers.begin())].push_back(k->second);
  }
  const MatX3i& F = actor.neutral.F;
  const MatX3d& X0 = actor.neutral.V;
  std::vector<double> at;
  double near_sum = 0, away_sum = 0, other_sum = 0;
  int64_t near_n = 0, away_n = 0, other_n = 0;
  for (auto& [f, markers] : listed) {
    std::sort(markers.begin(), markers.end());
    markers.erase(std::unique(markers.begin(), markers.end()), markers.end());
    std::vector<Vec3> centres;
    for (int k : markers) {
      const SurfacePoint& s = actor.markers[k].point;
      at.push_back((EvaluateSurfacePoint(s, F, recon[f]) - EvaluateSurfacePoint(s, F, truth[f])).norm());
      centres.push_back(EvaluateSurfacePoint(s, F, X0));
    }
    for (size_t k = 0; k < actor.markers.size(); ++k) {
      if (std::binary_search(markers.begin(), markers.end(), static_cast<int>(k))) continue;
      const SurfacePoint& s = actor.markers[k].point;
      other_sum += (EvaluateSurfacePoint(s, F, recon[f]) - EvaluateSurfacePoint(s, F, truth[f])).norm();
      ++other_n;
    }
    for (int v = 0; v < X0.rows(); ++v) {
      if (!face[v]) continue;
      const double e = (recon[f].row(v) - truth[f].row(v)).norm();
      const bool near = std::any_of(centres.begin(), centres.end(), [&](const Vec3& c) {
        return (X0.row(v).transpose() - c).norm() <= radius;
      });
      (near ? near_sum : away_sum) += e;
      ++(near ? near_n : away_n);
    }
  }
  auto mean = [](double sum, int64_t n) { return n > 0 ? sum / n : 0.0; };
  double at_sum = 0, at_max = 0;
  for (double e : at) {
    at_sum += e;
    at_max = std::max(at_max, e);
  }
  return {{"marker_frames", at.size()},
          {"frames", listed.size()},
          {"skipped", skipped},
          {"mean_mm", mean(at_sum, static_cast<int64_t>(at.size()))},
          {"max_mm", at_max},
          {"radius_mm", radius},
          {"near_mean_mm", mean(near_sum, near_n)},
          {"away_mean_mm", mean(away_sum, away_n)},
          {"other_markers_mean_mm", mean(other_sum, other_n)}};
}

}  // namespace

EvalOutput RunEval(const EvalInput& input, const EvalOptions& options) {
  HMC_CHECK(input.actor != nullptr);
  const Actor& actor = *input.actor;
  const ColorMap color_map = ParseColorMap(options.picture.color_map);
  const TriMesh& neutral = actor.neutral;
  const int V = neutral.NumVertices();
  MeshSequence truth = ReadMeshSequence(input.truth, &neutral);
  MeshSequence recon = ReadMeshSequence(input.recon, &neutral);
  for (const auto* seq : {&truth, &recon}) {
    const std::filesystem::path& path =
        seq == &truth ? input.truth : input.recon;
    for (const MatX3d& x : seq->frames) {
      if (x.rows() != V) {
        ThrowInputError(path, 0,
                        fmt::format("{} vertices per frame, the actor has {}",
                                    x.rows(), V));
      }
    }
  }
  const FrameMatch match = MatchFrames(truth, recon);
  const std::vector<int>& numbers = match.numbers;
  if (match.pairs.empty()) {
    ThrowInputError(input.recon, 0,
                    fmt::format("no frame numbers in common with {} (frames "
                                "{}..{})",
                                input.truth.string(), truth.start_frame,
                                truth.start_frame +
                                    static_cast<int>(truth.frames.size()) - 1));
  }
  std::vector<BundleFrame> bundle_rows;
  if (!input.bundles.empty()) bundle_rows = ReadBundlesCsv(input.bundles);

  StageTimer timer("eval");
  const int F = static_cast<int>(match.pairs.size());
  std::vector<int> picture_frames;
  if (!input.out.empty()) {
    if (!input.picture_frames.empty()) {
      for (int n : input.picture_frames) {
        if (std::find(numbers.begin(), numbers.end(), n) == numbers.end()) {
          throw InputError(
              fmt::format("--frames: frame {} is not in both sequences", n));
        }
        picture_frames.push_back(n);
      }
    } else {
      for (int q = 0; q < 4; ++q) {
        picture_frames.push_back(numbers[(F - 1) * q / 3]);
      }
    }
    std::sort(picture_frames.begin(), picture_frames.end());
    picture_frames.erase(
        std::unique(picture_frames.begin(), picture_frames.end()),
        picture_frames.end());
  }
  // The matched frames, in frame order (moved out of the sequences).
  std::vector<MatX3d> truth_frames(F), recon_frames(F);
  for (int f = 0; f < F; ++f) {
    truth_frames[f] = std::move(truth.frames[match.pairs[f].first]);
    recon_frames[f] = std::move(recon.frames[match.pairs[f].second]);
  }
  const SequenceEvaluator evaluator(actor, options.metrics);
  EvalOutput output;
  output.frames = F;
  output.metrics =
      evaluator.Evaluate(truth_frames, recon_frames, numbers,
                         input.bundles.empty() ? nullptr : &bundle_rows);
  const SequenceMetrics& metrics = output.metrics;
  const std::vector<FrameMetrics>& evals = metrics.per_frame;

  nlohmann::json per_frame = nlohmann::json::array();
  for (const FrameMetrics& e : evals) {
    per_frame.push_back({{"frame", e.frame},
                         {"face", StatsJson(e.face)},
                         {"all", StatsJson(e.all)},
                         {"bundle", StatsJson(e.bundle)},
                         {"detail_face_mm", e.detail_face},
                         {"detail_all_mm", e.detail_all}});
  }
  output.report = {
      {"actor", actor.name},
      {"truth", input.truth.string()},
      {"recon", input.recon.string()},
      {"bundle_targets",
       input.bundles.empty() ? "truth" : input.bundles.string()},
      {"frames", F},
      {"vertices", V},
      {"face_region",
       {{"radius_mm", options.metrics.face_radius_mm},
        {"vertices", metrics.face_vertices}}},
      {"detail", "uniform Laplacian coordinates"},
      {"overall", PooledMetricsJson(metrics)},
      {"per_frame", per_frame}};
  if (!input.at_markers.empty()) {
    output.report["at_markers"] =
        AtMarkersJson(actor, truth_frames, recon_frames, numbers,
                      evaluator.face_mask(),
                      input.at_markers, options.markers_radius_mm);
    output.report["at_markers"]["file"] = input.at_markers_file.string();
  }

  if (!input.out.empty()) {
    const std::filesystem::path& out = input.out;
    EnsureDirectory(out);
    WriteFileAtomic(out / "eval.json", output.report.dump(1) + "\n");
    WritePerFrameCsv(out / "per_frame.csv", evals);
    const int uv = options.uv_resolution;
    WriteExr(out / "error_uv_mean.exr",
             UvMap(neutral, metrics.mean_vertex_error, uv));
    double hi = options.picture.heat_max_mm;
    if (hi <= 0) {
      for (const FrameMetrics& e : evals) hi = std::max(hi, e.face.p95);
      if (hi <= 0) hi = 1e-3;
    }
    for (const int number : picture_frames) {
      const int f = static_cast<int>(
          std::find(numbers.begin(), numbers.end(), number) - numbers.begin());
      const Eigen::VectorXd err =
          VertexErrors(truth_frames[f], recon_frames[f]);
      WriteExr(out / fmt::format("error_uv_{:06d}.exr", number),
               UvMap(neutral, err, uv));
      WritePng(out / fmt::format("frame_{:06d}.png", number),
               ErrorPicture(neutral, truth_frames[f], recon_frames[f], err,
                            {fmt::format("truth {}", number), "reconstruction",
                             fmt::format("error, mean {:.3f} mm",
                                         evals[f].all.mean)},
                            hi, color_map, options.picture));
    }
  }
  return output;
}

}  // namespace hmc
