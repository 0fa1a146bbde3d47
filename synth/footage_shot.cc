#include "synth/footage_shot.h"

#include <algorithm>
#include <chrono>
#include <future>
#include <limits>
#include <memory>
#include <set>
#include <cmath>
#include <vector>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>
#include <spdlog/spdlog.h>

#include "core/allocator.h"
#include "core/day_markers.h"
#include "core/error.h"
#include "core/file_util.h"
#include "core/frame_data.h"
#include "core/image_io.h"
#include "core/logging.h"
#include "core/mesh_sequence.h"
#include "core/obj_io.h"
#include "core/parallel.h"
#include "synth/synth_random.h"

namespace hmc {

void SynthShotOptions::Register(OptionFields* fields) {
  performance.Register(fields);
  fields->Add("video", &video,
              "ffv1 (lossless .mkv per camera) | h264 (lossy .mp4 per camera, as a camera records) | "
              "png (a folder per camera) | none (ground truth "
              "only: no images, dots_2d.csv or contact sheet)")
      .OneOf({"ffv1", "h264", "png", "none"});
  fields->Add("bundle_noise_mm", &bundle_noise_mm,
              "> 0: also write bundles_helmet_noisy.csv, Gaussian noise of this std per "
              "coordinate (mm)")
      .In(0, 50);
  fields->Add("contact_frames", &contact_frames, "frames on the contact sheet (0 = none)")
      .In(0, 32);
  fields->Add("contact_dots", &contact_dots, "overlay the ground-truth dots on the contact sheet");
  fields->Add("contact_scale", &contact_scale, "contact sheet image scale").Above(0.05).AtMost(1);
  fields->Add("threads", &threads, "worker threads (0 = all cores)").In(0, 4096);
  rig.Register(fields);
  render.Register(fields);
  vary.Register(fields);
  paint.Register(fields);
  fields->Add("nominal_mm", &nominal_mm,
              "write calibration.yaml with each camera centre moved by this (mm; the truth goes "
              "to calibration_true.yaml)")
      .In(0, 50);
  fields->Add("nominal_deg", &nominal_deg, "... and each camera rotated by this (deg)").In(0, 20);
  fields->Add("nominal_focal_pct", &nominal_focal_pct, "... and its focal length scaled by 1 +- this (%)")
      .In(0, 20);
  fields->Add("knock_frame", &knock_frame,
              "from this frame on, knock_camera is moved (0 = no knock; the moved rig goes to "
              "calibration_knocked.yaml)")
      .AtLeast(0);
  fields->Add("knock_camera", &knock_camera, "the camera knocked");
  fields->Add("knock_mm", &knock_mm, "the knock's translation (mm)").In(0, 50);
  fields->Add("knock_deg", &knock_deg, "the knock's rotation (deg)").In(0, 20);
}

bool SynthShotOptions::Check() const {
  if (!performance.Check() || !rig.Check() || !render.Check() || !vary.Check() ||
      !paint.Check()) {
    return false;
  }
  if (!VaryRender(render, vary, static_cast<uint64_t>(performance.seed)).Check()) return false;
  CHECK_OPTION_LIMITS();
  return true;
}

std::string SynthShotSummary::BriefReport() const {
  return fmt::format(
      "{} frames x {} cameras rendered in {:.1f} s ({:.1f} stereo frames/s; {:.1f} s with "
      "writing); max edge error {:.4f} px, {:.2f}% of triangles split; {:.1f} visible "
      "dots per view, {:.1f} of them wholly",
      frames, cameras, render_seconds, render_seconds > 0 ? frames / render_seconds : 0.0,
      total_seconds, max_edge_error_px, 100 * split_fraction, mean_visible_dots,
      mean_full_dots);
}

namespace {

// Frontmost z of the neutral near the face's midline at height y (mm).
double FaceFrontZ(const TriMesh& neutral, double y) {
  double best = -std::numeric_limits<double>::infinity();
  for (int v = 0; v < neutral.NumVertices(); ++v) {
    if (std::abs(neutral.V(v, 1) - y) < 12 && std::abs(neutral.V(v, 0)) < 25) {
      best = std::max(best, neutral.V(v, 2));
    }
  }
  if (!std::isfinite(best)) best = neutral.V.col(2).maxCoeff();
  return best;
}

// Writes one camera's frames: a lossless FFV1 .mkv or a lossy H.264 .mp4
// (FFmpeg's default quality, with its compression artefacts; both written
// under a temporary name and renamed when complete) or a PNG folder (with
// an sRGB chunk when the values are sRGB-encoded, as a camera's PNGs say).
class FrameSink {
 public:
  FrameSink(const std::filesystem::path& out_dir, const std::string& name,
            const std::string& kind, double fps, cv::Size size, bool srgb)
      : kind_(kind), srgb_(srgb) {
    if (kind == "png") {
      dir_ = out_dir / name;
      EnsureDirectory(dir_);
      return;
    }
    const bool h264 = kind == "h264";
    const std::string ext = h264 ? ".mp4" : ".mkv";
    final_ = out_dir / (name + ext);
    temp_ = out_dir / ("." + name + ".partial" + ext);
    const int fourcc = h264 ? cv::VideoWriter::fourcc('a', 'v', 'c', '1')
                            : cv::VideoWriter::fourcc('F', 'F', 'V', '1');
    writer_.open(temp_.string(), cv::CAP_FFMPEG, fourcc, fps, size, false);
    if (!writer_.isOpened()) {
      ThrowInputError(final_, 0, "cannot open an {} video writer (OpenCV FFmpeg backend)",
                      h264 ? "H.264" : "FFV1");
    }
  }
  void Write(int frame, const cv::Mat& image) {
    if (kind_ == "png") {
      WritePng(dir_ / fmt::format("frame_{:06d}.png", frame), image, srgb_);
    } else {
      writer_.write(image);
    }
  }
  void Finish() {
    if (kind_ == "png") return;
    writer_.release();
    std::error_code error;
    std::filesystem::rename(temp_, final_, error);
    if (error) ThrowInputError(final_, 0, "cannot rename the finished video: {}", error.message());
  }

 private:
  std::string kind_;
  bool srgb_ = false;
  std::filesystem::path dir_, final_, temp_;
  cv::VideoWriter writer_;
};

cv::Mat ContactPanel(const cv::Mat& image, const std::vector<DotTruth>& dots, bool overlay,
                     double scale, const std::string& label) {
  cv::Mat small, bgr;
  cv::resize(image, small, cv::Size(), scale, scale, cv::INTER_AREA);
  cv::cvtColor(small, bgr, cv::COLOR_GRAY2BGR);
  if (overlay) {
    for (const DotTruth& dot : dots) {
      if (!dot.projects || !dot.facing) continue;
      const cv::Point2d p((dot.pixel.x() + 0.5) * scale - 0.5, (dot.pixel.y() + 0.5) * scale - 0.5);
      const int shift = 4;
      const cv::Point centre(static_cast<int>(std::lround(p.x * (1 << shift))),
                             static_cast<int>(std::lround(p.y * (1 << shift))));
      // Green: whole dot visible; yellow: partly hidden or grazing; red: hidden.
      const cv::Scalar color = dot.disc == DotDisc::kFull      ? cv::Scalar(60, 220, 60)
                               : dot.disc == DotDisc::kPartial ? cv::Scalar(40, 210, 230)
                                                               : cv::Scalar(40, 40, 230);
      cv::circle(bgr, centre, 3 << shift, color, 1, cv::LINE_AA, shift);
    }
  }
  cv::putText(bgr, label, cv::Point(8, 22), cv::FONT_HERSHEY_SIMPLEX, 0.6,
              cv::Scalar(255, 255, 255), 1, cv::LINE_AA);
  return bgr;
}

Vec3 RandomUnit(SynthRandom* rng) {
  const Vec3 v(rng->Normal(), rng->Normal(), rng->Normal());
  return v.normalized();
}

}  // namespace

Rigid3 KnockPose(const Rigid3& cam_from_helmet, double mm, double deg, uint64_t seed) {
  SynthRandom rng(seed);
  const Vec3 move = mm * RandomUnit(&rng);
  const Mat3 turn = Eigen::AngleAxisd(deg * M_PI / 180, RandomUnit(&rng)).toRotationMatrix();
  // helmet_from_cam' = (centre + move, R * turn): rotation about the centre.
  Rigid3 helmet_from_cam = cam_from_helmet.inverse();
  helmet_from_cam.linear() = Mat3(helmet_from_cam.linear() * turn);
  helmet_from_cam.translation() += move;
  return helmet_from_cam.inverse();
}

HelmetRig PerturbRig(const HelmetRig& rig, double mm, double deg, double focal_pct,
                     uint64_t seed) {
  HelmetRig out = rig;
  for (size_t c = 0; c < out.cameras.size(); ++c) {
    HelmetCamera& hc = out.cameras[c];
    const uint64_t stream = SynthRandom::Stream(seed, 0xCA11B000 + c).Next();
    hc.cam_from_helmet = KnockPose(hc.cam_from_helmet, mm, deg, stream);
    const double sign = (SynthRandom(stream ^ 1).Uniform() < 0.5) ? -1 : 1;
    hc.camera.fx *= 1 + sign * focal_pct / 100;
    hc.camera.fy *= 1 + sign * focal_pct / 100;
  }
  return out;
}

HelmetRig MakeShotRig(const FaceModel& model, const HelmetRigOptions& options) {
  return MakeHelmetRig(options, FaceFrontZ(model.neutral(), options.upper_camera_y),
                       FaceFrontZ(model.neutral(), options.lower_camera_y));
}

SynthShotSummary RunSynthShot(const FaceModel& model, const Actor& actor,
                              const SynthShotOptions& options,
                              const std::filesystem::path& out_dir) {
  if (!options.Check()) throw InputError("invalid synth shot options (see the message above)");
  const auto start = std::chrono::steady_clock::now();
  ThreadLimit thread_limit(options.threads);
  KeepFreedMemoryForReuse();
  EnsureDirectory(out_dir);
  const PerformanceOptions& perf = options.performance;
  const HelmetRig rig = MakeShotRig(model, options.rig);
  // The set of this seed (options.render itself when vary.on is false).
  const FootageRenderOptions render_options =
      VaryRender(options.render, options.vary, static_cast<uint64_t>(perf.seed));
  // The day's paint: where the dots really are (synth/paint.h).
  const uint64_t paint_seed = static_cast<uint64_t>(
      options.paint.seed >= 0 ? options.paint.seed : perf.seed);
  const PaintedDots painted = PaintDots(actor.neutral, actor.markers, options.paint, paint_seed);
  auto make_renderer = [&](int frame) {
    return std::make_unique<FootageRenderer>(model.neutral(), model.face().st,
                                             painted.At(frame), rig, render_options,
                                             static_cast<uint64_t>(perf.seed));
  };
  std::unique_ptr<FootageRenderer> renderer_ptr = make_renderer(1);
  const ShotPerformance performance = MakePerformance(model, perf);
  const int num_frames = perf.frames;
  const int num_cameras = renderer_ptr->NumCameras();
  const bool render = options.video != "none";
  const bool perturbed =
      options.nominal_mm > 0 || options.nominal_deg > 0 || options.nominal_focal_pct > 0;
  if (perturbed) {
    WriteCalibration(out_dir / "calibration.yaml",
                     PerturbRig(rig, options.nominal_mm, options.nominal_deg,
                                options.nominal_focal_pct, static_cast<uint64_t>(perf.seed)));
    WriteCalibration(out_dir / "calibration_true.yaml", rig);
  } else {
    WriteCalibration(out_dir / "calibration.yaml", rig);
  }
  int knock_camera = -1;
  HelmetRig knocked = rig;
  if (options.knock_frame > 0) {
    for (size_t c = 0; c < rig.cameras.size(); ++c) {
      if (rig.cameras[c].name == options.knock_camera) knock_camera = static_cast<int>(c);
    }
    if (knock_camera < 0) {
      throw InputError("synth shot: knock_camera '" + options.knock_camera + "' is not in the rig");
    }
    HelmetCamera& hc = knocked.cameras[knock_camera];
    hc.cam_from_helmet = KnockPose(hc.cam_from_helmet, options.knock_mm, options.knock_deg,
                                   SynthRandom::Stream(perf.seed, 0x0C0C).Next());
    WriteCalibration(out_dir / "calibration_knocked.yaml", knocked);
  }

  // The tags' corners in the rig before any knock (calibration_true.yaml).
  std::string tags_csv = "camera,tag,corner,x,y\n";
  for (int c = 0; c < num_cameras; ++c) {
    const auto corners = renderer_ptr->ProjectTagCorners(c);
    for (size_t t = 0; t < corners.size(); ++t) {
      for (int i = 0; i < 4; ++i) {
        tags_csv += fmt::format("{},{},{},{:.6f},{:.6f}\n", rig.cameras[c].name, rig.tags[t].id,
                                i, corners[t][i].x(), corners[t][i].y());
      }
    }
  }

  std::vector<FrameSink> sinks;
  sinks.reserve(num_cameras);
  for (const HelmetCamera& hc : render ? rig.cameras : std::vector<HelmetCamera>()) {
    sinks.emplace_back(out_dir, hc.name, options.video, perf.fps,
                       cv::Size(hc.camera.width, hc.camera.height),
                       options.render.transfer == "srgb");
  }
  std::set<int> contact;
  for (int i = 0; render && i < options.contact_frames; ++i) {
    contact.insert(static_cast<int>((i + 0.5) * num_frames / options.contact_frames));
  }
  std::vector<cv::Mat> contact_rows;

  MeshSequence truth;
  truth.start_frame = 1;
  truth.fps = perf.fps;
  std::vector<BundleFrame> bundles_head(num_frames), bundles_helmet(num_frames);
  std::vector<JawFrame> jaw(num_frames);
  std::string dots_csv = "frame,camera,marker,x,y,visible,disc,cx,cy,seen,cos,whole,wcx,wcy\n";
  std::vector<PoseFrame> poses(num_frames);
  SynthShotSummary summary;
  summary.frames = num_frames;
  summary.cameras = num_cameras;
  int64_t input_triangles = 0, split_triangles = 0, visible = 0, full = 0;
  const MatX3i& F = model.neutral().F;
  const int blur = render_options.motion_blur_samples;
  // Encoding runs beside the rendering: frame f's images are written while
  // frame f + 1 renders (FFV1 encoding is serial). One write task at a
  // time, in frame order, so the files are the same as written inline.
  std::future<void> writing;
  auto wait_for_writing = [&] {
    if (writing.valid()) writing.get();  // rethrows a write error
  };
  Progress progress("synth shot", num_frames);
  for (int f = 0; f < num_frames; ++f) {
    const int frame = truth.start_frame + f;
    if (f > 0 && frame == painted.lost_frame) {
      // Dots rubbed off from here on: the same scene without them.
      renderer_ptr = make_renderer(frame);
      if (knock_camera >= 0 && frame > options.knock_frame) {
        renderer_ptr->SetCamFromHelmet(knock_camera, knocked.cameras[knock_camera].cam_from_helmet);
      }
    }
    const FootageRenderer& renderer = *renderer_ptr;
    const std::vector<Marker> markers = painted.At(frame);
    if (knock_camera >= 0 && frame == options.knock_frame) {
      renderer_ptr->SetCamFromHelmet(knock_camera, knocked.cameras[knock_camera].cam_from_helmet);
    }
    const Eigen::VectorXd& a = performance.activations[f];
    truth.frames.push_back(model.Evaluate(a));
    const MatX3d& X = truth.frames.back();
    const Rigid3& head_from_helmet = performance.head_from_helmet[f];
    const SceneState state{&X, head_from_helmet};
    // Motion blur: sub-frame states across the shutter, centred on the frame.
    std::vector<MatX3d> blur_positions;
    std::vector<SceneState> samples;
    if (!render) {
      // Ground truth only: nothing to sample.
    } else if (blur > 1) {
      blur_positions.reserve(blur);
      for (int j = 0; j < blur; ++j) {
        const double tau = (j / (blur - 1.0) - 0.5) * render_options.shutter;  // frames
        const Eigen::VectorXd a_tau = ActivationsAt(performance, f + tau);
        blur_positions.push_back(model.Evaluate(a_tau));
        samples.push_back({&blur_positions.back(), HeadFromHelmetAt(perf, (f + tau) / perf.fps)});
      }
    } else {
      samples.push_back(state);
    }
    jaw[f] = {frame, model.JawPoseOf(a)};
    bundles_head[f].frame = frame;
    bundles_helmet[f].frame = frame;
    const Rigid3 helmet_from_head = head_from_helmet.inverse();
    for (const Marker& marker : markers) {
      const Vec3 p = EvaluateSurfacePoint(marker.point, F, X);
      bundles_head[f].bundles[marker.name] = p;
      bundles_helmet[f].bundles[marker.name] = helmet_from_head * p;
    }
    poses[f] = {frame, head_from_helmet};
    std::vector<cv::Mat> panels;
    std::vector<cv::Mat> images(render ? num_cameras : 0);
    for (int c = 0; c < static_cast<int>(images.size()); ++c) {
      const auto render_start = std::chrono::steady_clock::now();
      const uint64_t key = (static_cast<uint64_t>(perf.seed) << 32) ^
                           (static_cast<uint64_t>(frame) << 4) ^ static_cast<uint64_t>(c);
      const double shot_fraction = num_frames > 1 ? f / (num_frames - 1.0) : 0.0;
      const ViewRender view = renderer.Render(c, samples, key, true, shot_fraction);
      const std::vector<DotTruth> dots = renderer.ProjectDots(c, state, view);
      summary.render_seconds +=
          std::chrono::duration<double>(std::chrono::steady_clock::now() - render_start).count();
      summary.max_edge_error_px = std::max(summary.max_edge_error_px, view.stats.max_edge_error_px);
      input_triangles += view.stats.input_triangles;
      split_triangles += view.stats.split_triangles;
      images[c] = view.image;
      for (size_t m = 0; m < dots.size(); ++m) {
        if (!dots[m].projects) continue;
        visible += dots[m].visible;
        full += dots[m].disc == DotDisc::kFull;
        auto pair = [](const Vec2& p) {
          return p.allFinite() ? fmt::format("{:.6f},{:.6f}", p.x(), p.y()) : std::string(",");
        };
        dots_csv += fmt::format(
            "{},{},{},{:.6f},{:.6f},{},{},{},{:.3f},{:.3f},{},{}\n", frame, rig.cameras[c].name,
            markers[m].name, dots[m].pixel.x(), dots[m].pixel.y(), dots[m].visible ? 1 : 0,
            DotDiscName(dots[m].disc), pair(dots[m].centroid), dots[m].seen, dots[m].view_cos,
            dots[m].whole ? 1 : 0, pair(dots[m].whole_centroid));
      }
      if (contact.count(f)) {
        panels.push_back(ContactPanel(view.image, dots, options.contact_dots,
                                      options.contact_scale,
                                      fmt::format("frame {} {}", frame, rig.cameras[c].name)));
      }
    }
    wait_for_writing();
    writing = std::async(std::launch::async, [&sinks, frame, images = std::move(images)] {
      for (size_t c = 0; c < images.size(); ++c) sinks[c].Write(frame, images[c]);
    });
    if (!panels.empty()) {
      cv::Mat row;
      cv::hconcat(panels, row);
      contact_rows.push_back(row);
    }
    progress.Advance();
  }
  wait_for_writing();
  progress.Finish();
  for (FrameSink& sink : sinks) sink.Finish();

  // Ground truth.
  if (render) WriteFileAtomic(out_dir / "dots_2d.csv", dots_csv);
  WritePosesCsv(out_dir / "head_from_helmet.csv", poses);
  WriteBundlesCsv(out_dir / "bundles.csv", bundles_head);
  WriteBundlesCsv(out_dir / "bundles_helmet.csv", bundles_helmet);
  if (options.bundle_noise_mm > 0) {
    SynthRandom noise = SynthRandom::Stream(static_cast<uint64_t>(perf.seed), 51);
    for (BundleFrame& frame : bundles_helmet) {
      for (auto& [name, p] : frame.bundles) {
        for (int i = 0; i < 3; ++i) p[i] += options.bundle_noise_mm * noise.Normal();
      }
    }
    WriteBundlesCsv(out_dir / "bundles_helmet_noisy.csv", bundles_helmet);
  }
  WriteJawCsv(out_dir / "jaw.csv", jaw);
  WriteFileAtomic(out_dir / "tags_2d.csv", tags_csv);
  std::string paint_note = fmt::format("# painted dots (hmc synth shot, paint seed {}, jitter {} mm)\n",
                                       paint_seed, options.paint.jitter_mm);
  if (!painted.missing.empty()) {
    paint_note += fmt::format("# unpainted: {}\n", fmt::join(painted.missing, " "));
  }
  if (!painted.lost.empty()) {
    paint_note += fmt::format("# lost from frame {}: {}\n", painted.lost_frame,
                              fmt::join(painted.lost, " "));
  }
  WriteFileAtomic(out_dir / "painted_markers.csv",
                  FormatMarkersCsv(painted.markers, nullptr, paint_note));
  truth.topology = actor.neutral;
  WriteMeshSequence(out_dir / "truth.pc2", truth);
  WriteObj(out_dir / "neutral.obj", actor.neutral);
  if (!contact_rows.empty()) {
    cv::Mat sheet;
    cv::vconcat(contact_rows, sheet);
    WritePng(out_dir / "contact_sheet.png", sheet);
  }
  OptionFields used;
  SynthShotOptions copy = options;
  copy.Register(&used);
  WriteOptionsUsed(used, out_dir / "options_used.yaml", "synth shot");
  if (options.vary.on) {
    WriteFileAtomic(out_dir / "variation.yaml",
                    VariationYaml(render_options, static_cast<uint64_t>(perf.seed)));
  }

  const double total_views = static_cast<double>(num_frames) * num_cameras;
  summary.split_fraction =
      input_triangles > 0 ? static_cast<double>(split_triangles) / input_triangles : 0.0;
  summary.mean_visible_dots = visible / std::max(1.0, total_views);
  summary.mean_full_dots = full / std::max(1.0, total_views);
  summary.total_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return summary;
}

}  // namespace hmc
