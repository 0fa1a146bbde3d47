#include "tracking/undistort.h"

#include <random>

#include <gtest/gtest.h>

namespace hmc {
namespace {

// The remap is the exact KB model: the fisheye pixel a pinhole pixel
// samples unprojects to that pinhole pixel's ray, also far off axis.
TEST(UndistortTest, MapsAreExactToTheFisheyeModel) {
  FisheyeCamera camera;
  camera.width = 640;
  camera.height = 512;
  camera.fx = 350;
  camera.fy = 351.4;
  camera.cx = 322.5;
  camera.cy = 254.1;
  camera.k = {-0.012, 0.0035, -0.0009, 0.0001};
  for (double fov : {60.0, 110.0, 160.0}) {
    UndistortOptions options;
    options.fov_deg = fov;
    options.width = 300;
    options.height = 200;
    const PinholeView view = MakePinholeView(camera, options);
    cv::Mat map_x, map_y;
    MakeUndistortMaps(camera, view, &map_x, &map_y);
    ASSERT_EQ(map_x.cols, 300);
    ASSERT_EQ(map_x.rows, 200);
    std::mt19937 rng(static_cast<unsigned>(fov));
    for (int i = 0; i < 200; ++i) {
      const int u = static_cast<int>(rng() % 300), v = static_cast<int>(rng() % 200);
      const Vec2 fisheye(map_x.at<float>(v, u), map_y.at<float>(v, u));
      Vec3 bearing;
      ASSERT_TRUE(camera.Unproject(fisheye, &bearing));
      Vec2 back;
      ASSERT_TRUE(view.Project(bearing, &back));
      // float maps: ~1e-4 px of fisheye position.
      EXPECT_LT((back - Vec2(u, v)).norm(), 2e-3 * (1 + view.f / camera.fx)) << fov;
    }
  }
}

}  // namespace
}  // namespace hmc
