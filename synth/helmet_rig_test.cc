#include "synth/helmet_rig.h"

#include <cmath>
#include <filesystem>

#include <gtest/gtest.h>

#include "core/error.h"
#include "core/file_util.h"
#include "synth/lens_test_rigs.h"
#include "synth/synth_random.h"

namespace hmc {
namespace {

HelmetRig DefaultRig() { return MakeHelmetRig(HelmetRigOptions(), 110.0, 95.0); }

TEST(HelmetRigTest, WideFieldOfViewAndStackedCameras) {
  const HelmetRig rig = DefaultRig();
  ASSERT_EQ(rig.cameras.size(), 2u);
  for (const HelmetCamera& hc : rig.cameras) {
    const FisheyeCamera& cam = hc.camera;
    // Diagonal field of view: the angles off axis of the two ends of the
    // diagonal, from the unprojected corner rays.
    Vec3 a, b;
    ASSERT_TRUE(cam.Unproject(Vec2(-0.5, -0.5), &a));
    ASSERT_TRUE(cam.Unproject(Vec2(cam.width - 0.5, cam.height - 0.5), &b));
    const double diagonal_deg = (std::acos(a.z()) + std::acos(b.z())) * 180 / M_PI;
    EXPECT_GE(diagonal_deg, 120.0);
  }
  const Vec3 upper = rig.cameras[0].cam_from_helmet.inverse().translation();
  const Vec3 lower = rig.cameras[1].cam_from_helmet.inverse().translation();
  EXPECT_GT(upper.y(), lower.y() + 40);  // stacked vertically
  EXPECT_NEAR(upper.x(), lower.x(), 1e-9);
  // 15-20 cm from the face (front at z = 110 / 95).
  EXPECT_GT(upper.z() - 110, 150);
  EXPECT_LT(upper.z() - 110, 200);
}

// Round trip beyond 90 degrees off axis with the rig's lens: project then
// unproject returns the ray.
TEST(HelmetRigTest, FisheyeRoundTripBeyondNinetyDegrees) {
  const FisheyeCamera cam = DefaultRig().cameras[1].camera;
  SynthRandom rng(7);
  const double max_theta = cam.MaxTheta();
  ASSERT_GT(max_theta, M_PI / 2 + 0.2);
  int beyond = 0;
  for (int i = 0; i < 2000; ++i) {
    const double theta = rng.Uniform(0, max_theta - 1e-3);
    const double phi = rng.Uniform(0, 2 * M_PI);
    const Vec3 ray(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi),
                   std::cos(theta));
    const Vec3 point = ray * rng.Uniform(10, 500);
    Vec2 pixel;
    ASSERT_TRUE(cam.Project(point, &pixel));
    Vec3 back;
    ASSERT_TRUE(cam.Unproject(pixel, &back));
    EXPECT_LT((back - ray).norm(), 1e-9) << "theta " << theta;
    beyond += theta > M_PI / 2;
  }
  EXPECT_GT(beyond, 100);
}

TEST(HelmetRigTest, CalibrationRoundTrip) {
  const HelmetRig rig = DefaultRig();
  const auto dir = std::filesystem::temp_directory_path() / "hmc_helmet_rig_test";
  EnsureDirectory(dir);
  WriteCalibration(dir / "calibration.yaml", rig);
  const HelmetRig back = ReadCalibration(dir / "calibration.yaml");
  ASSERT_EQ(back.cameras.size(), rig.cameras.size());
  ASSERT_EQ(back.tags.size(), rig.tags.size());
  for (size_t c = 0; c < rig.cameras.size(); ++c) {
    const auto p = rig.cameras[c].camera.Params();
    const auto q = back.cameras[c].camera.Params();
    for (int i = 0; i < kNumFisheyeParams; ++i) EXPECT_DOUBLE_EQ(p[i], q[i]);
    EXPECT_EQ(back.cameras[c].camera.width, rig.cameras[c].camera.width);
    EXPECT_LT((back.cameras[c].cam_from_helmet.matrix() - rig.cameras[c].cam_from_helmet.matrix())
                  .norm(),
              1e-12);
    EXPECT_EQ(back.cameras[c].name, rig.cameras[c].name);
  }
  for (size_t t = 0; t < rig.tags.size(); ++t) {
    EXPECT_EQ(back.tags[t].id, rig.tags[t].id);
    EXPECT_DOUBLE_EQ(back.tags[t].size, rig.tags[t].size);
    EXPECT_LT((back.tags[t].helmet_from_tag.matrix() - rig.tags[t].helmet_from_tag.matrix()).norm(),
              1e-12);
  }
  WriteFileAtomic(dir / "broken.yaml", "%YAML:1.0\n---\ncameras: []\n");
  EXPECT_THROW(ReadCalibration(dir / "broken.yaml"), InputError);
  std::filesystem::remove_all(dir);
}

TEST(HelmetRigTest, TagsFaceBothCamerasAndAreInView) {
  const HelmetRig rig = DefaultRig();
  ASSERT_GE(rig.tags.size(), 3u);
  for (const HelmetTag& tag : rig.tags) {
    for (const HelmetCamera& hc : rig.cameras) {
      const Vec3 centre = tag.helmet_from_tag.translation();
      const Vec3 camera = hc.cam_from_helmet.inverse().translation();
      // The tag's printed side (-z of the tag frame) faces the camera.
      EXPECT_GT((camera - centre).normalized().dot(-tag.helmet_from_tag.linear().col(2)), 0.5);
      for (const Vec3& corner : tag.CornersInHelmet()) {
        Vec2 pixel;
        ASSERT_TRUE(hc.camera.Project(hc.cam_from_helmet * corner, &pixel));
        EXPECT_TRUE(hc.camera.IsInImage(pixel));
      }
    }
  }
}

// Issue 44, item 5: the renderer's rig takes any lens model; the model and
// its parameters reach calibration.yaml, and the tags stay in view of both
// cameras through a narrow pinhole lens and a double-sphere fisheye.
TEST(HelmetRigTest, EveryLensModelReachesTheCalibration) {
  const auto dir = std::filesystem::temp_directory_path() / "hmc_helmet_rig_model_test";
  EnsureDirectory(dir);
  const std::vector<HelmetRigOptions> lenses = OtherLensRigOptions();
  for (const HelmetRigOptions& options : lenses) {
    ASSERT_TRUE(options.Check()) << options.model;
    const HelmetRig rig = MakeHelmetRig(options, 110.0, 95.0);
    WriteCalibration(dir / "calibration.yaml", rig);
    const HelmetRig back = ReadCalibration(dir / "calibration.yaml");
    for (size_t c = 0; c < rig.cameras.size(); ++c) {
      const Camera& cam = back.cameras[c].camera;
      EXPECT_STREQ(CameraModelName(cam.model), options.model.c_str());
      EXPECT_EQ(cam.Params(), rig.cameras[c].camera.Params());
      for (const HelmetTag& tag : rig.tags) {
        for (const Vec3& corner : tag.CornersInHelmet()) {
          Vec2 pixel;
          ASSERT_TRUE(cam.Project(back.cameras[c].cam_from_helmet * corner, &pixel));
          EXPECT_TRUE(cam.IsInImage(pixel)) << options.model;
        }
      }
    }
  }
  const Camera pinhole = MakeCamera(lenses[0]);
  EXPECT_EQ(pinhole.k[RadTan::kRadTanP1], 0.0004);
  EXPECT_EQ(pinhole.k[RadTan::kRadTanK3], 0.001);
  HelmetRigOptions unknown;
  unknown.model = "fisheye";
  EXPECT_FALSE(unknown.Check());
}

}  // namespace
}  // namespace hmc
