#include "core/kalibr.h"

#include <cmath>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

#include "core/error.h"
#include "core/file_util.h"
#include "core/temp_dir.h"

namespace hmc {
namespace {

Rigid3 Pose(double ax, double ay, double az, const Vec3& t) {
  Rigid3 p = Rigid3::Identity();
  p.linear() = (Eigen::AngleAxisd(ax, Vec3::UnitX()) * Eigen::AngleAxisd(ay, Vec3::UnitY()) *
                Eigen::AngleAxisd(az, Vec3::UnitZ()))
                   .toRotationMatrix();
  p.translation() = t;
  return p;
}

HelmetRig TestRig() {
  HelmetRig rig;
  FisheyeCamera cam;
  cam.width = 1280;
  cam.height = 1024;
  cam.fx = 701.25;
  cam.fy = 699.5;
  cam.cx = 641.3;
  cam.cy = 509.7;
  cam.k = {-0.012, 0.0035, -0.0009, 0.0001};
  rig.cameras.push_back({"cam0", cam, Pose(0.3, -0.1, 0.05, Vec3(1, 20, -150))});
  cam.fx *= 1.004;
  cam.cx -= 5;
  rig.cameras.push_back({"cam1", cam, Pose(-0.35, 0.08, -0.02, Vec3(-2, -75, -140))});
  rig.tags.push_back({0, 22, Pose(0.1, 0.2, 0.3, Vec3(-90, -38, 60))});
  return rig;
}

void ExpectSameCameras(const HelmetRig& a, const HelmetRig& b, double pose_tol) {
  ASSERT_EQ(a.cameras.size(), b.cameras.size());
  for (size_t c = 0; c < a.cameras.size(); ++c) {
    const auto pa = a.cameras[c].camera.Params(), pb = b.cameras[c].camera.Params();
    for (int i = 0; i < kNumFisheyeParams; ++i) EXPECT_NEAR(pa[i], pb[i], 1e-12 * (1 + std::abs(pa[i])));
    EXPECT_EQ(a.cameras[c].camera.width, b.cameras[c].camera.width);
    EXPECT_EQ(a.cameras[c].camera.height, b.cameras[c].camera.height);
    EXPECT_LT((a.cameras[c].cam_from_helmet.matrix() - b.cameras[c].cam_from_helmet.matrix())
                  .norm(),
              pose_tol);
  }
}

TEST(KalibrTest, RoundTripKeepsTheCamerasAndTheirRelativePose) {
  const HelmetRig rig = TestRig();
  TempDir dir;
  const auto path = dir.path() / "camchain.yaml";
  WriteKalibrCamchain(path, rig);
  const std::vector<KalibrCamera> chain = ReadKalibrCamchain(path);
  ASSERT_EQ(chain.size(), 2u);
  EXPECT_FALSE(chain[0].has_cam_from_previous);
  EXPECT_TRUE(chain[1].has_cam_from_previous);
  // Applied to a rig whose cam1 is elsewhere: cam1 comes back where it was
  // relative to cam0.
  HelmetRig moved = rig;
  moved.cameras[1].cam_from_helmet = Rigid3::Identity();
  for (auto& hc : moved.cameras) hc.camera.fx = 500;
  ExpectSameCameras(ApplyKalibr(moved, chain, path), rig, 1e-9);
}

TEST(KalibrTest, CalibrationYamlIsReadByOpenCvAndProjectsAsCvFisheye) {
  const HelmetRig rig = TestRig();
  TempDir dir;
  const auto path = dir.path() / "calibration.yaml";
  WriteCalibration(path, rig);
  ExpectSameCameras(ReadCalibration(path), rig, 1e-9);
  // Plain OpenCV reads K and D, and cv::fisheye projects as our camera does.
  cv::FileStorage fs(path.string(), cv::FileStorage::READ);
  ASSERT_TRUE(fs.isOpened());
  const cv::FileNode cam = fs["cameras"][1];
  cv::Mat K, D;
  cam["K"] >> K;
  cam["D"] >> D;
  const FisheyeCamera& ours = rig.cameras[1].camera;
  const FisheyeCamera back = FisheyeCamera::FromOpenCv(K, D, cv::Size(ours.width, ours.height));
  std::vector<cv::Point3d> points = {{10, -20, 100}, {-50, 30, 60}, {80, 70, 40}};
  std::vector<cv::Point2d> projected;
  cv::fisheye::projectPoints(points, projected, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), K, D);
  for (size_t i = 0; i < points.size(); ++i) {
    Vec2 pixel;
    ASSERT_TRUE(back.Project(Vec3(points[i].x, points[i].y, points[i].z), &pixel));
    EXPECT_NEAR(pixel.x(), projected[i].x, 1e-6);
    EXPECT_NEAR(pixel.y(), projected[i].y, 1e-6);
  }
}

void ExpectRefused(const std::string& text, const std::string& key) {
  TempDir dir;
  const auto path = dir.path() / "camchain.yaml";
  WriteFileAtomic(path, text);
  try {
    ReadKalibrCamchain(path);
    FAIL() << "accepted a camchain without a valid " << key;
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("camchain.yaml"), std::string::npos) << what;
    EXPECT_NE(what.find(key), std::string::npos) << what;
  }
}

const char* kCam0 =
    "cam0:\n  camera_model: pinhole\n  distortion_model: equidistant\n"
    "  intrinsics: [700, 700, 640, 512]\n  distortion_coeffs: [-0.01, 0.003, -0.0009, 0.0001]\n"
    "  resolution: [1280, 1024]\n";

TEST(KalibrTest, BadCamchainsAreRefusedNamingTheKey) {
  const std::string cam1 =
      "cam1:\n  camera_model: pinhole\n  distortion_model: equidistant\n"
      "  intrinsics: [700, 700, 640, 512]\n  distortion_coeffs: [0, 0, 0, 0]\n"
      "  resolution: [1280, 1024]\n";
  ExpectRefused(std::string(kCam0) + cam1, "cam1.T_cn_cnm1");
  ExpectRefused(std::string(kCam0) + cam1 +
                    "  T_cn_cnm1: [[1, 0.1, 0, 0], [0, 1, 0, 0.06], [0, 0, 1, 0], [0, 0, 0, 1]]\n",
                "cam1.T_cn_cnm1");
  ExpectRefused("cam0:\n  camera_model: omni\n", "cam0.camera_model");
  ExpectRefused("cam0:\n  camera_model: pinhole\n  distortion_model: fov\n",
                "cam0.distortion_model");
  ExpectRefused("cam0:\n  camera_model: ds\n  distortion_model: radtan\n",
                "cam0.distortion_model");
  ExpectRefused("cam0:\n  camera_model: pinhole\n  distortion_model: equidistant\n"
                "  intrinsics: [700, 700, 640]\n",
                "cam0.intrinsics");
  ExpectRefused("cam0:\n  camera_model: pinhole\n  distortion_model: equidistant\n"
                "  intrinsics: [700, 700, 640, 512]\n  distortion_coeffs: [0, 0, 0, 0]\n",
                "cam0.resolution");
  ExpectRefused("something: 1\n", "cam0");
  // Found by fuzzing (docs/reliability.md): a resolution of 1e80 passed as
  // "an integer" and overflowed the conversion to int (UBSan).
  ExpectRefused("cam0:\n  camera_model: pinhole\n  distortion_model: equidistant\n"
                "  intrinsics: [700, 700, 640, 512]\n  distortion_coeffs: [0, 0, 0, 0]\n"
                "  resolution: [1e80, 1024]\n",
                "cam0.resolution");
}

}  // namespace
}  // namespace hmc
