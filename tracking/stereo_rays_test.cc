#include "tracking/stereo_rays.h"

#include <random>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

namespace hmc {
namespace {

HelmetCamera MakeCamera(const std::string& name, const Vec3& centre, double tilt_deg) {
  HelmetCamera hc;
  hc.name = name;
  hc.camera.width = 1280;
  hc.camera.height = 1024;
  hc.camera.fx = hc.camera.fy = 700;
  hc.camera.cx = 640;
  hc.camera.cy = 512;
  hc.camera.k = {-0.012, 0.0035, -0.0009, 0.0001};
  // Looking along -z of helmet space (at the face), tilted about x.
  Rigid3 helmet_from_cam = Rigid3::Identity();
  helmet_from_cam.linear() = Eigen::AngleAxisd(tilt_deg * M_PI / 180, Vec3::UnitX()) *
                             Eigen::AngleAxisd(M_PI, Vec3::UnitY()).toRotationMatrix();
  helmet_from_cam.translation() = centre;
  hc.cam_from_helmet = helmet_from_cam.inverse();
  return hc;
}

TEST(StereoRaysTest, RaysThroughAPointMeetAtIt) {
  const HelmetCamera a = MakeCamera("cam0", Vec3(0, -18, 160), 5);
  const HelmetCamera b = MakeCamera("cam1", Vec3(0, -78, 150), -15);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-60, 60);
  for (int i = 0; i < 50; ++i) {
    const Vec3 p(u(rng), u(rng), 0.3 * u(rng));
    Vec2 pa, pb;
    ASSERT_TRUE(a.camera.Project(a.cam_from_helmet * p, &pa));
    ASSERT_TRUE(b.camera.Project(b.cam_from_helmet * p, &pb));
    const RayApproach hit = ClosestApproach(PixelRay(a, pa), PixelRay(b, pb));
    ASSERT_TRUE(hit.ok);
    EXPECT_LT(hit.gap, 1e-6);
    EXPECT_LT((hit.midpoint - p).norm(), 1e-6);
    // Moving one pixel off the epipolar line opens a gap.
    const RayApproach off = ClosestApproach(PixelRay(a, pa + Vec2(3, 0)), PixelRay(b, pb));
    EXPECT_GT(off.gap, 0.1);
  }
}

}  // namespace
}  // namespace hmc
