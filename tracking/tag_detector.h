// Helmet AprilTag detection (`hmc calibrate`): the AprilTag 3 library
// (Olson, "AprilTag: A robust and flexible visual fiducial system", ICRA
// 2011; Wang & Olson, "AprilTag 2", IROS 2016) on the 8-bit grey fisheye
// image. The tags are small (~20 mm at ~150 mm) and near the image edge,
// where the fisheye bends straight edges little over a tag's extent, so the
// detector's line fit holds without undistortion.
//
// The library fits straight lines to the tag's edges and intersects them.
// In a fisheye image a straight edge is curved: at ~30 degrees off axis
// the edges of a 70 px tag bow by ~0.3 px, and the fitted corners move by
// 0.1-0.3 px away from the image centre (measured on `hmc synth shot`
// footage against the exact projections). DetectRectified removes that
// bias: each tag found in the fisheye image is detected again in a small
// virtual pinhole view aimed at it (resampled bilinearly through the
// camera model), where its edges are straight, and the corners are mapped
// back through the exact model (core/camera_fisheye.h).
//
// Corners are returned in hmc's pixel convention (OpenCV: the centre of the
// top-left pixel at (0, 0)); the library reports pixel centres at +0.5, which
// is subtracted here (docs/formats.md, "calibration.yaml"). Corner order is
// the library's: tag coordinates (-1, 1), (1, 1), (1, -1), (-1, -1), as
// HelmetTag::CornersInHelmet (core/calibration.h).
#pragma once

#include <array>
#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "core/camera.h"
#include "core/options.h"
#include "core/types.h"

namespace hmc {

struct TagDetectorOptions {
  double quad_decimate = 1;    // image decimation before the quad search (1 = full resolution)
  double quad_sigma = 0;       // Gaussian blur before the quad search (px; 0 = none)
  double min_margin = 20;      // smallest decision margin of a kept detection
  int max_hamming = 1;         // most corrected bits of a kept detection
  bool rectify = true;         // re-detect each tag in a pinhole view of it (straight edges)
  double coarse_decimate = 2;  // with rectify: decimation of the full-image search (1 = none)

  void Register(OptionFields* fields);
  bool Check() const;
};

struct TagDetection {
  int id = 0;
  std::array<Vec2, 4> corners;  // px, hmc convention, the library's order
  double margin = 0;            // decision margin
  int hamming = 0;              // corrected bits
};

class TagDetector {
 public:
  // Throws InputError for a family the library does not have (tag36h11,
  // tag25h9, tag16h5, tagStandard41h12, tagStandard52h13, tagCircle21h7,
  // tagCircle49h12, tagCustom48h12, tag36h10).
  TagDetector(const std::string& family, const TagDetectorOptions& options);
  ~TagDetector();
  TagDetector(const TagDetector&) = delete;
  TagDetector& operator=(const TagDetector&) = delete;

  // Detections in `grey` (CV_8U, one channel), sorted by id. Not
  // thread-safe (one detector per thread).
  std::vector<TagDetection> Detect(const cv::Mat& grey) const;

  // As Detect, then (options.rectify) each tag re-detected in a virtual
  // pinhole view aimed at it; a tag not found again keeps its fisheye
  // detection. `camera`: the image's fisheye model.
  std::vector<TagDetection> DetectRectified(const cv::Mat& grey,
                                            const FisheyeCamera& camera) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace hmc
