#include "eval/run_eval.h"

#include <algorithm>

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
