// `hmc eval --actor DIR --truth T --recon R [--bundles bundles.csv]
// [--out DIR] [--frames 1,10,...] [--json]`: how far a reconstruction is
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

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <sstream>
#include <string>

#include "apps/command.h"
#include "apps/picture_options.h"
#include "blending/eval_metrics.h"
#include "core/actor.h"
#include "core/color_map.h"
#include "core/error.h"
#include "core/file_util.h"
#include "core/frame_data.h"
#include "core/image_io.h"
#include "core/logging.h"
#include "core/mesh_metrics.h"
#include "core/mesh_sequence.h"
#include "core/raster.h"
#include "core/render_mesh.h"

namespace hmc {
namespace {

struct EvalOptions {
  MeshMetricsOptions metrics;
  int uv_resolution = 512;  // side of the UV-space error maps (px)
  PictureOptions picture;

  void Register(OptionFields* fields) {
    metrics.Register(fields);
    fields->Add("uv_resolution", &uv_resolution,
                "side of the UV-space error maps (px)");
    picture.Register(fields);
  }
  bool Check() const {
    if (!metrics.Check()) return false;
    if (uv_resolution < 8 || uv_resolution > 8192) {
      spdlog::error("uv_resolution must be in [8, 8192]");
      return false;
    }
    return picture.Check();
  }
};

struct EvalCommand {
  std::string actor_dir;
  std::string truth;
  std::string recon;
  std::string bundles;
  std::string out;
  std::string frames;
  bool json = false;
  EvalOptions options;
};

nlohmann::json StatsJson(const ErrorStats& s) {
  return {{"count", s.count},
          {"mean_mm", s.mean},
          {"rms_mm", s.rms},
          {"p95_mm", s.p95},
          {"max_mm", s.max}};
}

std::vector<int> ParseFrames(const std::string& text) {
  std::vector<int> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    try {
      size_t used = 0;
      out.push_back(std::stoi(item, &used));
      if (used != item.size()) throw std::invalid_argument(item);
    } catch (const std::exception&) {
      throw InputError("--frames: '" + item + "' is not a frame number");
    }
  }
  return out;
}

// Per-vertex values rasterised over the UV layout: CV_32F, v = 1 at the top
// row; NaN where no triangle covers the pixel.
cv::Mat UvMap(const TriMesh& mesh, const Eigen::VectorXd& values, int size) {
  cv::Mat image(size, size, CV_32F,
                cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
  if (!mesh.HasUVs()) return image;
  Eigen::VectorXd uv_values(mesh.UV.rows());
  uv_values.setZero();
  for (int t = 0; t < mesh.NumFaces(); ++t) {
    for (int c = 0; c < 3; ++c)
      uv_values[mesh.FUV(t, c)] = values[mesh.F(t, c)];
  }
  MatX3d screen(mesh.UV.rows(), 3);
  for (int i = 0; i < mesh.UV.rows(); ++i) {
    screen.row(i) << mesh.UV(i, 0) * size - 0.5,
        (1 - mesh.UV(i, 1)) * size - 0.5, 0.0;
  }
  RasterOptions ro;
  ro.width = size;
  ro.height = size;
  const RasterBuffer buffer =
      Rasterize(screen, Eigen::VectorXd(), mesh.FUV, ro);
  for (int y = 0; y < size; ++y) {
    for (int x = 0; x < size; ++x) {
      const int index = buffer.Index(x, y);
      if (!buffer.Covered(index)) continue;
      image.at<float>(y, x) = static_cast<float>(
          InterpolateAt(buffer, index, mesh.FUV, uv_values)(0));
    }
  }
  return image;
}

int Run(EvalCommand& cmd, OptionBinding& binding) {
  binding.Apply();
  RequireValid(cmd.options, "eval");
  const ColorMap color_map = ParseColorMap(cmd.options.picture.color_map);
  const Actor actor = LoadActor(cmd.actor_dir);
  const TriMesh& neutral = actor.neutral;
  const int V = neutral.NumVertices();
  MeshSequence truth = ReadMeshSequence(cmd.truth, &neutral);
  MeshSequence recon = ReadMeshSequence(cmd.recon, &neutral);
  for (const auto* seq : {&truth, &recon}) {
    const std::string& path = seq == &truth ? cmd.truth : cmd.recon;
    for (const MatX3d& x : seq->frames) {
      if (x.rows() != V) {
        ThrowInputError(path, 0,
                        fmt::format("{} vertices per frame, the actor has {}",
                                    x.rows(), V));
      }
    }
  }
  // Frames present in both, by number.
  std::vector<std::pair<int, int>> pairs;  // (truth index, recon index)
  std::vector<int> numbers;
  for (size_t i = 0; i < truth.frames.size(); ++i) {
    const int number = truth.start_frame + static_cast<int>(i);
    const int j = number - recon.start_frame;
    if (j >= 0 && j < static_cast<int>(recon.frames.size())) {
      pairs.emplace_back(static_cast<int>(i), j);
      numbers.push_back(number);
    }
  }
  if (pairs.empty()) {
    ThrowInputError(cmd.recon, 0,
                    fmt::format("no frame numbers in common with {} (frames "
                                "{}..{})",
                                cmd.truth, truth.start_frame,
                                truth.start_frame +
                                    static_cast<int>(truth.frames.size()) - 1));
  }
  std::vector<BundleFrame> bundle_rows;
  if (!cmd.bundles.empty()) bundle_rows = ReadBundlesCsv(cmd.bundles);

  StageTimer timer("eval");
  const int F = static_cast<int>(pairs.size());
  std::vector<int> picture_frames;
  if (!cmd.out.empty()) {
    if (!cmd.frames.empty()) {
      for (int n : ParseFrames(cmd.frames)) {
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
    truth_frames[f] = std::move(truth.frames[pairs[f].first]);
    recon_frames[f] = std::move(recon.frames[pairs[f].second]);
  }
  const SequenceEvaluator evaluator(actor, cmd.options.metrics);
  const SequenceMetrics metrics =
      evaluator.Evaluate(truth_frames, recon_frames, numbers,
                         cmd.bundles.empty() ? nullptr : &bundle_rows);
  const std::vector<FrameMetrics>& evals = metrics.per_frame;
  const int face_vertices = metrics.face_vertices;

  nlohmann::json per_frame = nlohmann::json::array();
  for (const FrameMetrics& e : evals) {
    per_frame.push_back({{"frame", e.frame},
                         {"face", StatsJson(e.face)},
                         {"all", StatsJson(e.all)},
                         {"bundle", StatsJson(e.bundle)},
                         {"detail_face_mm", e.detail_face},
                         {"detail_all_mm", e.detail_all}});
  }
  const nlohmann::json report = {
      {"actor", actor.name},
      {"truth", cmd.truth},
      {"recon", cmd.recon},
      {"bundle_targets", cmd.bundles.empty() ? "truth" : cmd.bundles},
      {"frames", F},
      {"vertices", V},
      {"face_region",
       {{"radius_mm", cmd.options.metrics.face_radius_mm},
        {"vertices", face_vertices}}},
      {"detail", "uniform Laplacian coordinates"},
      {"overall",
       {{"face", StatsJson(metrics.face)},
        {"all", StatsJson(metrics.all)},
        {"bundle", StatsJson(metrics.bundle)},
        {"detail_face_mm", metrics.detail_face},
        {"detail_all_mm", metrics.detail_all},
        {"flicker_face_mm_per_frame2", metrics.flicker_face.mean},
        {"flicker_all_mm_per_frame2", metrics.flicker_all.mean},
        {"flicker_frames_used", metrics.flicker_all.frames_used}}},
      {"per_frame", per_frame}};

  if (!cmd.out.empty()) {
    const std::filesystem::path out(cmd.out);
    EnsureDirectory(out);
    WriteFileAtomic(out / "eval.json", report.dump(1) + "\n");
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
    WriteFileAtomic(out / "per_frame.csv", csv);
    const int uv = cmd.options.uv_resolution;
    WriteExr(out / "error_uv_mean.exr",
             UvMap(neutral, metrics.mean_vertex_error, uv));
    double hi = cmd.options.picture.heat_max_mm;
    if (hi <= 0) {
      for (const FrameMetrics& e : evals) hi = std::max(hi, e.face.p95);
      if (hi <= 0) hi = 1e-3;
    }
    MeshRenderOptions ro;
    ro.width = cmd.options.picture.image_width;
    ro.height = cmd.options.picture.image_height;
    for (const int number : picture_frames) {
      const int f = static_cast<int>(
          std::find(numbers.begin(), numbers.end(), number) - numbers.begin());
      const Eigen::VectorXd err =
          VertexErrors(truth_frames[f], recon_frames[f]);
      WriteExr(out / fmt::format("error_uv_{:06d}.exr", number),
               UvMap(neutral, err, uv));
      TriMesh t = neutral, r = neutral;
      t.V = truth_frames[f];
      r.V = recon_frames[f];
      Eigen::Matrix<double, 2, 3> box = BoundingBox(t.V);
      const Eigen::Matrix<double, 2, 3> rbox = BoundingBox(r.V);
      box.row(0) = box.row(0).cwiseMin(rbox.row(0));
      box.row(1) = box.row(1).cwiseMax(rbox.row(1));
      ro.frame_box = box;
      const cv::Mat panels = ComposeLabelledPanels(
          {RenderMesh(t, ro), RenderMesh(r, ro),
           RenderMeshScalars(r, err, 0.0, hi, color_map, ro)},
          {fmt::format("truth {}", number), "reconstruction",
           fmt::format("error, mean {:.3f} mm", evals[f].all.mean)});
      WritePng(out / fmt::format("frame_{:06d}.png", number),
               WithColorBar(panels, color_map, 0.0, hi, "mm"));
    }
    WriteOptionsUsed(binding.fields(), out / "options_used.yaml");
  }

  if (cmd.json) {
    fmt::print("{}\n", report.dump());
  } else {
    fmt::print(
        "hmc eval: {} frames, {} vertices ({} in the face region, "
        "within {} mm of a marker)\n",
        F, V, face_vertices, cmd.options.metrics.face_radius_mm);
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
  spdlog::info("eval: {} frames, face mean {:.4f} mm, all mean {:.4f} mm", F,
               metrics.face.mean, metrics.all.mean);
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
  app->add_option("--out", cmd->out,
                  "Folder for eval.json, per_frame.csv, UV error maps (EXR) "
                  "and pictures (PNG)");
  app->add_option("--frames", cmd->frames,
                  "Frames to picture, comma separated (default: four spread "
                  "over the sequence)");
  app->add_flag("--json", cmd->json,
                "Print one JSON object instead of a table");
  auto binding = BindOptions(app, &cmd->options);
  return [cmd, binding] { return Run(*cmd, *binding); };
}

}  // namespace hmc
