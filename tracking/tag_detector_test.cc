#include "tracking/tag_detector.h"

#include <cmath>
#include <cstdio>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "core/error.h"
#include "synth/tag_render.h"

namespace hmc {
namespace {

FisheyeCamera Camera() {
  FisheyeCamera cam;
  cam.width = 1280;
  cam.height = 1024;
  cam.fx = cam.fy = 700;
  cam.cx = 639.5;
  cam.cy = 511.5;
  cam.k = {-0.012, 0.0035, -0.0009, 0.0001};
  return cam;
}

// A tag (black-border edge `size` mm) at `centre` (camera frame) facing the
// camera, rendered into a grey image by 6 x 6 supersampled rays through the
// exact fisheye model; the rest of the image is mid grey.
cv::Mat RenderTag(const FisheyeCamera& cam, const TagPattern& pattern, const Vec3& centre,
                  double size, std::array<Vec2, 4>* corners) {
  const Vec3 z = centre.normalized();  // the tag's +z: into the plate, away from the camera
  // Turned in its plane by 0.4 rad and tilted by 0.5 rad about its columns,
  // as the helmet's tags are seen (edges off the pixel grid).
  const Vec3 x0 = Vec3::UnitY().cross(z).normalized() * -1;
  const Vec3 y0 = z.cross(x0);
  const Vec3 x1 = std::cos(0.4) * x0 + std::sin(0.4) * y0;
  const Vec3 y1 = z.cross(x1);
  const Vec3 x = x1;
  const Vec3 y = std::cos(0.5) * y1 + std::sin(0.5) * z;
  const Vec3 zt = x.cross(y);
  const double h = size / 2;
  const Vec3 tag_corners[4] = {centre + h * (-x + y), centre + h * (x + y), centre + h * (x - y),
                               centre + h * (-x - y)};
  double min_x = 1e9, max_x = -1e9, min_y = 1e9, max_y = -1e9;
  for (int k = 0; k < 4; ++k) {
    EXPECT_TRUE(cam.Project(tag_corners[k], &(*corners)[k]));
    min_x = std::min(min_x, (*corners)[k].x());
    max_x = std::max(max_x, (*corners)[k].x());
    min_y = std::min(min_y, (*corners)[k].y());
    max_y = std::max(max_y, (*corners)[k].y());
  }
  cv::Mat image(cam.height, cam.width, CV_8U, cv::Scalar(128));
  const double margin = 0.4 * (max_x - min_x);
  const int n = 6;
  for (int py = static_cast<int>(min_y - margin); py <= max_y + margin; ++py) {
    for (int px = static_cast<int>(min_x - margin); px <= max_x + margin; ++px) {
      double sum = 0;
      for (int j = 0; j < n; ++j) {
        for (int i = 0; i < n; ++i) {
          Vec3 ray;
          const Vec2 pixel(px - 0.5 + (i + 0.5) / n, py - 0.5 + (j + 0.5) / n);
          EXPECT_TRUE(cam.Unproject(pixel, &ray));
          const double t = centre.dot(zt) / ray.dot(zt);
          const Vec3 p = t * ray - centre;
          const double v = pattern.Sample(p.dot(x) / size, p.dot(y) / size);
          sum += v < 0 ? 0.5 : 0.1 + 0.8 * v;
        }
      }
      image.at<uint8_t>(py, px) = static_cast<uint8_t>(std::lround(255 * sum / (n * n)));
    }
  }
  return image;
}

TEST(TagDetectorTest, RectifiedCornersAreUnbiasedOffAxis) {
  const FisheyeCamera cam = Camera();
  const TagPattern pattern(3);
  TagDetector detector("tag36h11", TagDetectorOptions());
  TagDetectorOptions plain_options;
  plain_options.rectify = false;
  TagDetector plain("tag36h11", plain_options);
  // On axis, 30 and 45 degrees off it.
  for (const Vec3& centre : {Vec3(0, 0, 150), Vec3(-85, 10, 150), Vec3(100, -100, 140)}) {
    std::array<Vec2, 4> truth;
    const cv::Mat image = RenderTag(cam, pattern, centre, 22, &truth);
    const std::vector<TagDetection> rectified = detector.DetectRectified(image, cam);
    const std::vector<TagDetection> fisheye = plain.DetectRectified(image, cam);
    ASSERT_EQ(rectified.size(), 1u) << centre.transpose();
    ASSERT_EQ(fisheye.size(), 1u);
    EXPECT_EQ(rectified[0].id, 3);
    double sq = 0, sq_plain = 0;
    for (int k = 0; k < 4; ++k) {
      sq += (rectified[0].corners[k] - truth[k]).squaredNorm();
      sq_plain += (fisheye[0].corners[k] - truth[k]).squaredNorm();
    }
    const double rms = std::sqrt(sq / 4), rms_plain = std::sqrt(sq_plain / 4);
    std::printf("tag at %s: corner RMS rectified %.3f px, in the fisheye image %.3f px\n",
                fmt::format("({:.0f}, {:.0f}, {:.0f})", centre.x(), centre.y(), centre.z()).c_str(),
                rms, rms_plain);
    // On axis both see straight edges (AprilTag's own accuracy on a clean
    // image, ~0.1 px); off axis the fisheye bends them and biases the
    // library's corners, which the rectified view removes.
    EXPECT_LT(rms, 0.15) << centre.transpose();
    if (centre.x() != 0) {
      EXPECT_LT(rms, 0.1) << centre.transpose();
      EXPECT_LT(rms, 0.5 * rms_plain) << centre.transpose();
    }
  }
}

TEST(TagDetectorTest, UnknownFamilyIsRefused) {
  EXPECT_THROW(TagDetector("tag99h1", TagDetectorOptions()), InputError);
}

}  // namespace
}  // namespace hmc
