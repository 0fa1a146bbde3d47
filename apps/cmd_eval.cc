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
  int image_width = 360;    // size of one picture panel (px)
  int image_height = 450;
  double heat_max_mm = 0.0;           // top of the heat-map scale (mm); 0: the
                                      // largest face-region 95th percentile of
                                      // the frames
  std::string color_map = "viridis";  // heat-map colours

  void Register(OptionFields* fields) {
    metrics.Register(fields);
    fields->Add("uv_resolution", &uv_resolution,
                "side of the UV-space error maps (px)");
    fields->Add("image_width", &image_width, "picture panel width (px)");
    fields->Add("image_height", &image_height, "picture panel height (px)");
    fields->Add("heat_max_mm", &heat_max_mm,
                "top of the heat-map scale (mm); 0: the largest face-region "
                "95th percentile of the frames");
    fields->Add("color_map", &color_map,
                "heat-map colours: viridis, inferno, turbo");
  }
  bool Check() const {
    if (!metrics.Check()) return false;
    if (uv_resolution < 8 || uv_resolution > 8192) {
      spdlog::error("uv_resolution must be in [8, 8192]");
      return false;
    }
    if (image_width < 32 || image_height < 32) {
      spdlog::error("image_width and image_height must be >= 32");
      return false;
    }
    if (!(heat_max_mm >= 0) || !std::isfinite(heat_max_mm)) {
      spdlog::error("heat_max_mm must be >= 0");
      return false;
    }
    return true;
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

struct FrameEval {
  int frame = 0;
  ErrorStats face, all, bundle;
  double detail_face = 0, detail_all = 0;  // mean |delta_T - delta_R| (mm)
};

nlohmann::json StatsJson(const ErrorStats& s) {
  return {{"count", s.count},
          {"mean_mm", s.mean},
          {"rms_mm", s.rms},
          {"p95_mm", s.p95},
          {"max_mm", s.max}};
}

double Mean(const std::vector<double>& v) {
  double sum = 0;
  for (double x : v) sum += x;
  return v.empty() ? 0.0 : sum / v.size();
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
  const ColorMap color_map = ParseColorMap(cmd.options.color_map);
  const Actor actor = LoadActor(cmd.actor_dir);
  const TriMesh& neutral = actor.neutral;
  const int V = neutral.NumVertices();
  const MeshSequence truth = ReadMeshSequence(cmd.truth, &neutral);
  const MeshSequence recon = ReadMeshSequence(cmd.recon, &neutral);
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
  std::map<int, BundleFrame> bundles_by_frame;
  if (!cmd.bundles.empty()) {
    for (BundleFrame& b : ReadBundlesCsv(cmd.bundles)) {
      bundles_by_frame[b.frame] = std::move(b);
    }
  }

  StageTimer timer("eval");
  std::vector<SurfacePoint> sites;
  for (const Marker& m : actor.markers) sites.push_back(m.point);
  const std::vector<uint8_t> face =
      FaceRegionMask(neutral, sites, cmd.options.metrics.face_radius_mm);
  int face_vertices = 0;
  for (uint8_t m : face) face_vertices += m;
  const Eigen::SparseMatrix<double> laplacian = UniformLaplacian(neutral.F, V);

  const int F = static_cast<int>(pairs.size());
  std::vector<FrameEval> evals(F);
  std::vector<double> pool_face, pool_all, pool_bundle, pool_detail_face,
      pool_detail_all;
  pool_face.reserve(static_cast<size_t>(face_vertices) * F);
  pool_all.reserve(static_cast<size_t>(V) * F);
  Eigen::VectorXd error_sum = Eigen::VectorXd::Zero(V);
  std::map<int, Eigen::VectorXd> kept_errors;  // for the pictures
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
  Progress progress("eval", F);
  for (int f = 0; f < F; ++f) {
    const MatX3d& t = truth.frames[pairs[f].first];
    const MatX3d& r = recon.frames[pairs[f].second];
    FrameEval& e = evals[f];
    e.frame = numbers[f];
    const Eigen::VectorXd err = VertexErrors(t, r);
    error_sum += err;
    std::vector<double> face_err = Select(err, face);
    std::vector<double> all_err = Select(err, {});
    pool_face.insert(pool_face.end(), face_err.begin(), face_err.end());
    pool_all.insert(pool_all.end(), all_err.begin(), all_err.end());
    e.face = ComputeErrorStats(&face_err);
    e.all = ComputeErrorStats(&all_err);
    const Eigen::VectorXd detail = DetailErrors(laplacian, t, r);
    const std::vector<double> detail_face = Select(detail, face);
    e.detail_face = Mean(detail_face);
    e.detail_all = detail.mean();
    pool_detail_face.insert(pool_detail_face.end(), detail_face.begin(),
                            detail_face.end());
    pool_detail_all.insert(pool_detail_all.end(), detail.data(),
                           detail.data() + detail.size());
    // Bundle targets: the truth's surface points, or the given bundles.
    MatX3d targets(sites.size(), 3);
    if (cmd.bundles.empty()) {
      for (size_t k = 0; k < sites.size(); ++k) {
        targets.row(k) =
            EvaluateSurfacePoint(sites[k], neutral.F, t).transpose();
      }
    } else {
      targets.setConstant(std::numeric_limits<double>::quiet_NaN());
      const auto it = bundles_by_frame.find(e.frame);
      if (it != bundles_by_frame.end()) {
        for (size_t k = 0; k < sites.size(); ++k) {
          const auto b = it->second.bundles.find(actor.markers[k].name);
          if (b != it->second.bundles.end())
            targets.row(k) = b->second.transpose();
        }
      }
    }
    std::vector<double> residuals =
        BundleResiduals(neutral.F, sites, r, targets);
    pool_bundle.insert(pool_bundle.end(), residuals.begin(), residuals.end());
    e.bundle = ComputeErrorStats(&residuals);
    if (std::binary_search(picture_frames.begin(), picture_frames.end(),
                           e.frame)) {
      kept_errors[e.frame] = err;
    }
    progress.Advance();
  }
  progress.Finish();
  const ErrorStats overall_face = ComputeErrorStats(&pool_face);
  const ErrorStats overall_all = ComputeErrorStats(&pool_all);
  const ErrorStats overall_bundle = ComputeErrorStats(&pool_bundle);
  const double overall_detail_face = Mean(pool_detail_face);
  const double overall_detail_all = Mean(pool_detail_all);

  nlohmann::json per_frame = nlohmann::json::array();
  for (const FrameEval& e : evals) {
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
       {{"face", StatsJson(overall_face)},
        {"all", StatsJson(overall_all)},
        {"bundle", StatsJson(overall_bundle)},
        {"detail_face_mm", overall_detail_face},
        {"detail_all_mm", overall_detail_all}}},
      {"per_frame", per_frame}};

  if (!cmd.out.empty()) {
    const std::filesystem::path out(cmd.out);
    EnsureDirectory(out);
    WriteFileAtomic(out / "eval.json", report.dump(1) + "\n");
    std::string csv =
        "frame,face_mean_mm,face_rms_mm,face_p95_mm,face_max_mm,all_mean_mm,"
        "all_rms_mm,all_p95_mm,all_max_mm,bundle_mean_mm,bundle_max_mm,"
        "detail_face_mm,detail_all_mm\n";
    for (const FrameEval& e : evals) {
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
             UvMap(neutral, error_sum / static_cast<double>(F), uv));
    double hi = cmd.options.heat_max_mm;
    if (hi <= 0) {
      for (const FrameEval& e : evals) hi = std::max(hi, e.face.p95);
      if (hi <= 0) hi = 1e-3;
    }
    MeshRenderOptions ro;
    ro.width = cmd.options.image_width;
    ro.height = cmd.options.image_height;
    for (const auto& [number, err] : kept_errors) {
      const int f = static_cast<int>(
          std::find(numbers.begin(), numbers.end(), number) - numbers.begin());
      WriteExr(out / fmt::format("error_uv_{:06d}.exr", number),
               UvMap(neutral, err, uv));
      TriMesh t = neutral, r = neutral;
      t.V = truth.frames[pairs[f].first];
      r.V = recon.frames[pairs[f].second];
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
    row("face", overall_face);
    row("all", overall_all);
    row("bundle", overall_bundle);
    fmt::print("detail (mean |dL|, mm): face {:.4f}, all {:.4f}\n",
               overall_detail_face, overall_detail_all);
  }
  spdlog::info("eval: {} frames, face mean {:.4f} mm, all mean {:.4f} mm", F,
               overall_face.mean, overall_all.mean);
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
