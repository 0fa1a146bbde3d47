#include "tracking/tag_detector.h"

#include <algorithm>
#include <cmath>
#include <functional>

#include <opencv2/imgproc.hpp>

#include <apriltag/apriltag.h>
#include <apriltag/common/image_u8.h>
#include <apriltag/tag16h5.h>
#include <apriltag/tag25h9.h>
#include <apriltag/tag36h10.h>
#include <apriltag/tag36h11.h>
#include <apriltag/tagCircle21h7.h>
#include <apriltag/tagCircle49h12.h>
#include <apriltag/tagCustom48h12.h>
#include <apriltag/tagStandard41h12.h>
#include <apriltag/tagStandard52h13.h>
#include <spdlog/spdlog.h>

#include "core/error.h"

namespace hmc {

void TagDetectorOptions::Register(OptionFields* fields) {
  fields->SetGroup("tags");
  fields->Add("quad_decimate", &quad_decimate,
              "image decimation before the quad search (1 = full resolution)")
      .In(1, 8);
  fields->Add("quad_sigma", &quad_sigma, "Gaussian blur before the quad search (px; 0 = none)")
      .In(0, 10);
  fields->Add("min_margin", &min_margin, "smallest decision margin of a kept detection").AtLeast(0);
  fields->Add("max_hamming", &max_hamming, "most corrected bits of a kept detection").In(0, 3);
  fields->Add("rectify", &rectify,
              "re-detect each tag in a virtual pinhole view of it, where its edges are straight");
  fields->Add("coarse_decimate", &coarse_decimate,
              "with rectify: decimation of the full-image search (1 = full resolution)")
      .In(1, 8);
  fields->SetGroup("");
}

bool TagDetectorOptions::Check() const {
  CHECK_OPTION_LIMITS();
  return true;
}

struct TagDetector::Impl {
  TagDetectorOptions options;
  apriltag_family_t* family = nullptr;
  std::function<void(apriltag_family_t*)> destroy;
  apriltag_detector_t* detector = nullptr;
};

TagDetector::TagDetector(const std::string& family, const TagDetectorOptions& options)
    : impl_(std::make_unique<Impl>()) {
  impl_->options = options;
  struct Family {
    const char* name;
    apriltag_family_t* (*create)();
    void (*destroy)(apriltag_family_t*);
  };
  static const Family kFamilies[] = {
      {"tag36h11", tag36h11_create, tag36h11_destroy},
      {"tag36h10", tag36h10_create, tag36h10_destroy},
      {"tag25h9", tag25h9_create, tag25h9_destroy},
      {"tag16h5", tag16h5_create, tag16h5_destroy},
      {"tagStandard41h12", tagStandard41h12_create, tagStandard41h12_destroy},
      {"tagStandard52h13", tagStandard52h13_create, tagStandard52h13_destroy},
      {"tagCircle21h7", tagCircle21h7_create, tagCircle21h7_destroy},
      {"tagCircle49h12", tagCircle49h12_create, tagCircle49h12_destroy},
      {"tagCustom48h12", tagCustom48h12_create, tagCustom48h12_destroy},
  };
  for (const Family& f : kFamilies) {
    if (family == f.name) {
      impl_->family = f.create();
      impl_->destroy = f.destroy;
    }
  }
  if (impl_->family == nullptr) {
    throw InputError("unknown AprilTag family '" + family + "'");
  }
  impl_->detector = apriltag_detector_create();
  apriltag_detector_add_family_bits(impl_->detector, impl_->family, options.max_hamming);
  impl_->detector->quad_decimate = static_cast<float>(options.quad_decimate);
  impl_->detector->quad_sigma = static_cast<float>(options.quad_sigma);
  impl_->detector->nthreads = 1;
  impl_->detector->refine_edges = true;
}

TagDetector::~TagDetector() {
  if (impl_->detector) apriltag_detector_destroy(impl_->detector);
  if (impl_->family) impl_->destroy(impl_->family);
}

namespace {

std::vector<TagDetection> RunDetector(apriltag_detector_t* detector, const cv::Mat& grey,
                                      const TagDetectorOptions& options) {
  HMC_CHECK(grey.type() == CV_8UC1);
  cv::Mat continuous = grey.isContinuous() ? grey : grey.clone();
  image_u8_t image{continuous.cols, continuous.rows, static_cast<int32_t>(continuous.step),
                   continuous.data};
  zarray_t* detections = apriltag_detector_detect(detector, &image);
  std::vector<TagDetection> out;
  for (int i = 0; i < zarray_size(detections); ++i) {
    apriltag_detection_t* det;
    zarray_get(detections, i, &det);
    if (det->decision_margin < options.min_margin || det->hamming > options.max_hamming) {
      continue;
    }
    TagDetection d;
    d.id = det->id;
    d.margin = det->decision_margin;
    d.hamming = det->hamming;
    for (int k = 0; k < 4; ++k) d.corners[k] = Vec2(det->p[k][0] - 0.5, det->p[k][1] - 0.5);
    out.push_back(d);
  }
  apriltag_detections_destroy(detections);
  std::sort(out.begin(), out.end(),
            [](const TagDetection& a, const TagDetection& b) { return a.id < b.id; });
  return out;
}

}  // namespace

std::vector<TagDetection> TagDetector::DetectRectified(const cv::Mat& grey,
                                                       const FisheyeCamera& camera) const {
  if (!impl_->options.rectify) return Detect(grey);
  impl_->detector->quad_decimate = static_cast<float>(impl_->options.coarse_decimate);
  std::vector<TagDetection> coarse = RunDetector(impl_->detector, grey, impl_->options);
  impl_->detector->quad_decimate = static_cast<float>(impl_->options.quad_decimate);
  for (TagDetection& d : coarse) {
    // The virtual pinhole camera: aimed at the tag's centre, focal length
    // the fisheye's, big enough for the tag and a margin of 60 % of it.
    Vec2 centre = Vec2::Zero();
    for (const Vec2& c : d.corners) centre += c / 4;
    double extent = 0;
    for (const Vec2& c : d.corners) extent = std::max(extent, (c - centre).norm());
    Vec3 axis;
    if (!camera.Unproject(centre, &axis)) continue;
    const Vec3 x_axis = Vec3::UnitY().cross(axis).normalized();
    Mat3 cam_from_view;
    cam_from_view << x_axis, axis.cross(x_axis), axis;
    const double f = camera.fx;
    const int size = 2 * static_cast<int>(std::ceil(1.6 * extent)) + 24;
    const double half = (size - 1) / 2.0;
    cv::Mat map_x(size, size, CV_32F), map_y(size, size, CV_32F);
    bool inside = true;
    for (int v = 0; v < size && inside; ++v) {
      for (int u = 0; u < size; ++u) {
        const Vec3 ray = cam_from_view * Vec3((u - half) / f, (v - half) / f, 1);
        Vec2 pixel;
        if (!camera.Project(ray, &pixel)) {
          inside = false;
          break;
        }
        map_x.at<float>(v, u) = static_cast<float>(pixel.x());
        map_y.at<float>(v, u) = static_cast<float>(pixel.y());
      }
    }
    if (!inside) continue;
    cv::Mat view;
    cv::remap(grey, view, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
    for (const TagDetection& r : RunDetector(impl_->detector, view, impl_->options)) {
      if (r.id != d.id) continue;
      TagDetection back = r;
      bool ok = true;
      for (int k = 0; k < 4; ++k) {
        const Vec3 ray =
            cam_from_view * Vec3((r.corners[k].x() - half) / f, (r.corners[k].y() - half) / f, 1);
        ok = ok && camera.Project(ray, &back.corners[k]);
      }
      if (ok) d = back;
      break;
    }
  }
  return coarse;
}

std::vector<TagDetection> TagDetector::Detect(const cv::Mat& grey) const {
  return RunDetector(impl_->detector, grey, impl_->options);
}

}  // namespace hmc
