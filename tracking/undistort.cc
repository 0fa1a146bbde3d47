#include "tracking/undistort.h"

#include <chrono>
#include <cmath>
#include <map>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>
#include <spdlog/spdlog.h>

#include "core/error.h"
#include "core/file_util.h"
#include "core/image_io.h"
#include "core/logging.h"
#include "core/parallel.h"
#include "core/tracks_2d.h"
#include "tracking/overlay.h"

namespace hmc {

void UndistortOptions::Register(OptionFields* fields) {
  footage.Register(fields);
  fields->Add("camera", &camera, "cam0 | cam1 | both (camera names from the calibration)");
  fields->Add("fov_deg", &fov_deg, "horizontal field of view of the pinhole view (deg)")
      .Above(1).Below(179);
  fields->Add("width", &width, "pinhole image width (px; 0 = the camera's)").In(0, 16384);
  fields->Add("height", &height, "pinhole image height (px; 0 = the camera's)").In(0, 16384);
  fields->Add("video", &video, "write an FFV1 .mkv per camera instead of PNG frames");
}

bool UndistortOptions::Check() const {
  CHECK_OPTION_LIMITS();
  if (camera.empty()) {
    spdlog::error("undistort options: camera must be a camera name or both");
    return false;
  }
  return footage.Check();
}

std::string UndistortSummary::BriefReport() const {
  return fmt::format("{} frames, {} views written, {} skipped, in {:.1f} s", frames, views,
                     skipped_views, seconds);
}

bool PinholeView::Project(const Vec3& bearing, Vec2* pixel) const {
  if (!(bearing.z() > 1e-9)) return false;
  *pixel = Vec2(f * bearing.x() / bearing.z() + cx, f * bearing.y() / bearing.z() + cy);
  return true;
}

PinholeView MakePinholeView(const FisheyeCamera& camera, const UndistortOptions& options) {
  PinholeView view;
  view.width = options.width > 0 ? options.width : camera.width;
  view.height = options.height > 0 ? options.height : camera.height;
  view.f = 0.5 * view.width / std::tan(0.5 * options.fov_deg * M_PI / 180);
  view.cx = 0.5 * (view.width - 1);
  view.cy = 0.5 * (view.height - 1);
  return view;
}

void MakeUndistortMaps(const FisheyeCamera& camera, const PinholeView& view, cv::Mat* map_x,
                       cv::Mat* map_y) {
  map_x->create(view.height, view.width, CV_32F);
  map_y->create(view.height, view.width, CV_32F);
  ParallelFor(0, view.height, [&](int64_t v) {
    float* mx = map_x->ptr<float>(static_cast<int>(v));
    float* my = map_y->ptr<float>(static_cast<int>(v));
    for (int u = 0; u < view.width; ++u) {
      const Vec3 ray((u - view.cx) / view.f, (v - view.cy) / view.f, 1);
      Vec2 p;
      if (camera.Project(ray, &p)) {
        mx[u] = static_cast<float>(p.x());
        my[u] = static_cast<float>(p.y());
      } else {
        mx[u] = my[u] = -1;
      }
    }
  });
}

UndistortSummary RunUndistort(const UndistortInput& input, const UndistortOptions& options) {
  if (!options.Check()) throw InputError("invalid undistort options (see the message above)");
  const auto start = std::chrono::steady_clock::now();
  const HelmetRig rig = ReadCalibration(input.calibration);
  const std::vector<std::string> names = rig.CameraNames();
  std::vector<cv::Size> sizes;
  for (const HelmetCamera& hc : rig.cameras) sizes.emplace_back(hc.camera.width, hc.camera.height);
  std::vector<int> selected;
  for (int c = 0; c < static_cast<int>(names.size()); ++c) {
    if (options.camera == "both" || options.camera == names[c]) selected.push_back(c);
  }
  if (selected.empty()) {
    ThrowInputError(input.calibration, 0, "no camera named '{}' (camera: a name or both)",
                    options.camera);
  }
  // Tracks by (frame, camera).
  std::map<std::pair<int, std::string>, std::vector<Track2d>> tracks;
  if (!input.tracks.empty()) {
    for (const Track2d& t : ReadTracks2dCsv(input.tracks)) tracks[{t.frame, t.camera}].push_back(t);
  }
  FootageReader reader(input.shot, names, options.footage, sizes);
  EnsureDirectory(input.out);
  std::vector<PinholeView> views(names.size());
  std::vector<cv::Mat> map_x(names.size()), map_y(names.size());
  std::vector<cv::VideoWriter> writers(names.size());
  std::vector<std::filesystem::path> temp(names.size()), final_path(names.size());
  for (int c : selected) {
    views[c] = MakePinholeView(rig.cameras[c].camera, options);
    MakeUndistortMaps(rig.cameras[c].camera, views[c], &map_x[c], &map_y[c]);
    if (options.video) {
      final_path[c] = input.out / (names[c] + ".mkv");
      temp[c] = input.out / ("." + names[c] + ".partial.mkv");
      writers[c].open(temp[c].string(), cv::CAP_FFMPEG, cv::VideoWriter::fourcc('F', 'F', 'V', '1'),
                      30, cv::Size(views[c].width, views[c].height), !input.tracks.empty());
      if (!writers[c].isOpened()) {
        ThrowInputError(final_path[c], 0, "cannot open an FFV1 video writer (OpenCV FFmpeg backend)");
      }
    } else {
      EnsureDirectory(input.out / names[c]);
    }
  }
  UndistortSummary summary;
  Progress progress("undistort", reader.num_frames());
  FootageFrame frame;
  while (reader.Next(&frame)) {
    ++summary.frames;
    for (int c : selected) {
      cv::Mat image;
      if (frame.images[c].empty()) {
        ++summary.skipped_views;
        if (!options.video) continue;
        image = cv::Mat::zeros(views[c].height, views[c].width, CV_8U);  // keep the timing
      } else {
        cv::remap(ToGrey8(frame.images[c]), image, map_x[c], map_y[c], cv::INTER_LINEAR,
                  cv::BORDER_CONSTANT, cv::Scalar(0));
      }
      if (!input.tracks.empty()) {
        cv::Mat bgr;
        cv::cvtColor(image, bgr, cv::COLOR_GRAY2BGR);
        auto it = tracks.find({frame.frame, names[c]});
        if (it != tracks.end()) {
          for (const Track2d& t : it->second) {
            Vec3 bearing;
            Vec2 p;
            if (!rig.cameras[c].camera.Unproject(t.pixel, &bearing) ||
                !views[c].Project(bearing, &p)) {
              continue;
            }
            DrawNamedDot(&bgr, p, t.marker);
          }
        }
        image = bgr;
      }
      if (options.video) {
        writers[c].write(image);
      } else {
        WritePng(input.out / names[c] / fmt::format("frame_{:06d}.png", frame.frame), image);
      }
      ++summary.views;
    }
    progress.Advance();
  }
  progress.Finish();
  for (const std::string& w : reader.warnings()) spdlog::warn("undistort: {}", w);
  for (int c : selected) {
    if (!options.video) continue;
    writers[c].release();
    std::error_code error;
    std::filesystem::rename(temp[c], final_path[c], error);
    if (error) ThrowInputError(final_path[c], 0, "cannot rename the finished video: {}", error.message());
  }
  OptionFields used;
  UndistortOptions copy = options;
  copy.Register(&used);
  WriteOptionsUsed(used, input.out / "options_used.yaml", "undistort");
  summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return summary;
}

}  // namespace hmc
