// `hmc undistort`: fisheye frames remapped to pinhole views for review and
// for other tools (docs/tracking.md, "Undistortion"; files: docs/formats.md).
//
// The pinhole view shares the camera's centre and axes; its pixel (u, v)
// sees the ray ((u - c_x) / f, (v - c_y) / f, 1), f = (W / 2) / tan(F / 2)
// for the horizontal field of view F. The remap table holds, per pinhole
// pixel, the exact projection of that ray through the camera's lens model
// (core/camera.h; not OpenCV's undistortion, wrong beyond ~90 degrees), and
// cv::remap samples the fisheye frame there (bilinear).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "core/calibration.h"
#include "core/options.h"
#include "tracking/footage_reader.h"

namespace hmc {

struct UndistortOptions {
  FootageOptions footage;       // cam0, cam1, frames, offset1 (top level)
  std::string camera = "both";  // cam0 | cam1 | both (camera names from the calibration)
  double fov_deg = 110;         // horizontal field of view of the pinhole view (deg)
  int width = 0;                // pinhole image width (px; 0 = the camera's)
  int height = 0;               // pinhole image height (px; 0 = the camera's)
  bool video = false;           // write an FFV1 .mkv per camera instead of PNG frames

  void Register(OptionFields* fields);
  bool Check() const;
};

// The pinhole camera of a view: intrinsics of the remap.
struct PinholeView {
  int width = 0, height = 0;
  double f = 0, cx = 0, cy = 0;  // px
  // The pinhole pixel of a bearing in the camera frame; false behind it.
  bool Project(const Vec3& bearing, Vec2* pixel) const;
};
PinholeView MakePinholeView(const FisheyeCamera& camera, const UndistortOptions& options);

// map_x, map_y (CV_32F, the view's size): the fisheye pixel each pinhole
// pixel samples; -1 where the ray does not project.
void MakeUndistortMaps(const FisheyeCamera& camera, const PinholeView& view, cv::Mat* map_x,
                       cv::Mat* map_y);

struct UndistortInput {
  std::filesystem::path shot;
  std::filesystem::path calibration;
  std::filesystem::path out;     // folder to write
  std::filesystem::path tracks;  // tracks_2d.csv to draw ("" = none)
};

struct UndistortSummary {
  int frames = 0;
  int views = 0;
  int skipped_views = 0;
  double seconds = 0;
  std::string BriefReport() const;
};

// Writes per camera OUT/<camera>/frame_NNNNNN.png or OUT/<camera>.mkv, and
// OUT/options_used.yaml. Throws InputError naming the file on bad input.
UndistortSummary RunUndistort(const UndistortInput& input, const UndistortOptions& options);

}  // namespace hmc
