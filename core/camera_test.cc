// The lens models behind Camera (core/camera.h): projection and
// unprojection are inverse over the whole one-to-one domain of each model,
// the Jet Jacobians match finite differences, pinhole_radtan agrees with
// OpenCV's cv::projectPoints, and calibration.yaml and Kalibr camchains
// keep every model and parameter (basalt test/test_camera.cpp is the model).
#include "core/camera.h"

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include <ceres/jet.h>
#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>

#include "core/calibration.h"
#include "core/error.h"
#include "core/file_util.h"
#include "core/kalibr.h"
#include "core/temp_dir.h"

namespace hmc {
namespace {


double Uniform(std::mt19937* rng, double lo, double hi) {
  return std::uniform_real_distribution<double>(lo, hi)(*rng);
}

// A random lens of `model` as rigs have them: Kannala-Brandt fisheyes up to
// 200 degrees, radial-tangential lenses from barrel to pincushion with
// small decentring, double-sphere lenses from 150 to beyond 200 degrees.
Camera RandomLens(CameraModel model, std::mt19937* rng) {
  Camera c;
  c.model = model;
  c.width = 1280;
  c.height = 1024;
  c.fx = Uniform(rng, 300, 900);
  c.fy = c.fx * Uniform(rng, 0.98, 1.02);
  c.cx = 639.5 + Uniform(rng, -20, 20);
  c.cy = 511.5 + Uniform(rng, -20, 20);
  switch (model) {
    case CameraModel::kKannalaBrandt:
      c.k = {Uniform(rng, -0.05, 0.05), Uniform(rng, -0.01, 0.01), Uniform(rng, -0.003, 0.003),
             Uniform(rng, -0.001, 0.001), 0};
      break;
    case CameraModel::kPinholeRadTan:
      c.k = {Uniform(rng, -0.4, 0.2), Uniform(rng, -0.1, 0.2), Uniform(rng, -2e-3, 2e-3),
             Uniform(rng, -2e-3, 2e-3), Uniform(rng, -0.05, 0.05)};
      break;
    case CameraModel::kDoubleSphere:
      c.k = {Uniform(rng, -0.4, 0.8), Uniform(rng, 0.3, 0.8), 0, 0, 0};
      break;
  }
  return c;
}

// A unit direction uniformly distributed over the cap within `max_theta`
// of the optical axis.
Vec3 RandomBearing(std::mt19937* rng, double max_theta) {
  const double cos_theta = Uniform(rng, std::cos(max_theta), 1.0);
  const double sin_theta = std::sqrt(1 - cos_theta * cos_theta);
  const double phi = Uniform(rng, -M_PI, M_PI);
  return Vec3(sin_theta * std::cos(phi), sin_theta * std::sin(phi), cos_theta);
}

// The round trip's reach: the whole domain but a sliver at its edge, where
// the model's slope goes to zero and any inverse loses its digits
// (pinhole_radtan: up to 85 degrees, past any real lens's field).
double TestedTheta(const Camera& c) {
  const double limit = c.MaxTheta();
  if (c.model == CameraModel::kPinholeRadTan) return std::min(0.97 * limit, 85 * M_PI / 180);
  return 0.995 * limit;
}

class CameraModelSeeded : public ::testing::TestWithParam<std::tuple<CameraModel, int>> {};

TEST_P(CameraModelSeeded, ProjectThenUnprojectIsIdentityOverTheWholeField) {
  const auto [model, seed] = GetParam();
  std::mt19937 rng(seed);
  for (int lens = 0; lens < 8; ++lens) {
    const Camera c = RandomLens(model, &rng);
    const double max_theta = TestedTheta(c);
    ASSERT_GT(max_theta, 0.5) << CameraModelName(model);
    for (int i = 0; i < 500; ++i) {
      const Vec3 bearing = RandomBearing(&rng, max_theta);
      const Vec3 point = bearing * Uniform(&rng, 10, 500);
      Vec2 pixel;
      ASSERT_TRUE(c.Project(point, &pixel)) << CameraModelName(model) << " " << bearing.transpose();
      Vec3 back;
      ASSERT_TRUE(c.Unproject(pixel, &back)) << CameraModelName(model) << " " << pixel.transpose();
      EXPECT_NEAR(back.norm(), 1.0, 1e-12);
      const double angle = std::atan2(back.cross(bearing).norm(), back.dot(bearing));
      EXPECT_LT(angle, 1e-9) << CameraModelName(model) << " theta "
                             << std::acos(bearing.z()) * 180 / M_PI << " deg";
    }
  }
}

TEST_P(CameraModelSeeded, UnprojectThenProjectIsIdentityOnTheImage) {
  const auto [model, seed] = GetParam();
  std::mt19937 rng(seed + 100);
  for (int lens = 0; lens < 4; ++lens) {
    const Camera c = RandomLens(model, &rng);
    int unprojected = 0;
    for (int i = 0; i < 500; ++i) {
      const Vec2 pixel(Uniform(&rng, -0.5, c.width - 0.5), Uniform(&rng, -0.5, c.height - 0.5));
      Vec3 bearing;
      if (!c.Unproject(pixel, &bearing)) {
        // Only a pixel beyond the image of the domain may fail: farther from
        // the principal point than the edge of the tested field in its
        // direction (a strong barrel lens's image ends inside the sensor).
        const Vec2 m((pixel.x() - c.cx) / c.fx, (pixel.y() - c.cy) / c.fy);
        const double phi = std::atan2(m.y(), m.x());
        const double theta = TestedTheta(c);
        Vec2 edge;
        ASSERT_TRUE(c.Project(Vec3(std::sin(theta) * std::cos(phi),
                                   std::sin(theta) * std::sin(phi), std::cos(theta)),
                              &edge));
        const Vec2 m_edge((edge.x() - c.cx) / c.fx, (edge.y() - c.cy) / c.fy);
        EXPECT_GT(m.norm(), 0.99 * m_edge.norm())
            << CameraModelName(model) << " refused " << pixel.transpose();
        continue;
      }
      ++unprojected;
      Vec2 back;
      ASSERT_TRUE(c.Project(bearing * 100, &back)) << CameraModelName(model);
      EXPECT_LT((back - pixel).norm(), 1e-6) << CameraModelName(model) << " " << pixel.transpose();
    }
    EXPECT_GT(unprojected, 0) << CameraModelName(model);
  }
}

// d pixel / d (intrinsics, point) from ceres::Jet against central finite
// differences.
TEST_P(CameraModelSeeded, JetJacobianMatchesFiniteDifferences) {
  const auto [model, seed] = GetParam();
  constexpr int kN = kNumCameraParams + 3;
  using Jet = ceres::Jet<double, kN>;
  std::mt19937 rng(seed + 200);
  for (int trial = 0; trial < 50; ++trial) {
    const Camera c = RandomLens(model, &rng);
    const Vec3 point = RandomBearing(&rng, 0.98 * TestedTheta(c)) * Uniform(&rng, 20, 300);
    double x[kN];
    const auto params = c.Params();
    for (int j = 0; j < kNumCameraParams; ++j) x[j] = params[j];
    for (int j = 0; j < 3; ++j) x[kNumCameraParams + j] = point[j];
    Jet jets[kN];
    for (int j = 0; j < kN; ++j) jets[j] = Jet(x[j], j);
    Jet pixel[2];
    ASSERT_TRUE(Camera::Project(model, jets, jets + kNumCameraParams, pixel));
    for (int j = 0; j < kN; ++j) {
      const double h = 1e-6 * std::max(1.0, std::abs(x[j]));
      double plus[kN], minus[kN];
      std::copy(x, x + kN, plus);
      std::copy(x, x + kN, minus);
      plus[j] += h;
      minus[j] -= h;
      double pp[2], pm[2];
      ASSERT_TRUE(Camera::Project(model, plus, plus + kNumCameraParams, pp));
      ASSERT_TRUE(Camera::Project(model, minus, minus + kNumCameraParams, pm));
      for (int r = 0; r < 2; ++r) {
        const double numeric = (pp[r] - pm[r]) / (2 * h);
        EXPECT_NEAR(pixel[r].v[j], numeric, 1e-5 * std::max(1.0, std::abs(numeric)))
            << CameraModelName(model) << " d pixel[" << r << "] / d x[" << j << "]";
      }
    }
  }
}

INSTANTIATE_TEST_SUITE_P(
    Models, CameraModelSeeded,
    ::testing::Combine(::testing::Values(CameraModel::kKannalaBrandt, CameraModel::kPinholeRadTan,
                                         CameraModel::kDoubleSphere),
                       ::testing::Values(1, 7, 29)));

// An independent oracle: OpenCV's pinhole projection with the same
// distCoeffs (k1, k2, p1, p2, k3).
TEST(CameraTest, RadTanProjectsAsCvProjectPoints) {
  std::mt19937 rng(5);
  for (int lens = 0; lens < 10; ++lens) {
    const Camera c = RandomLens(CameraModel::kPinholeRadTan, &rng);
    std::vector<cv::Point3d> points;
    for (int i = 0; i < 50; ++i) {
      const Vec3 p = RandomBearing(&rng, TestedTheta(c)) * Uniform(&rng, 10, 300);
      points.emplace_back(p.x(), p.y(), p.z());
    }
    std::vector<cv::Point2d> projected;
    cv::projectPoints(points, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), cv::Mat(c.K()), c.D(),
                      projected);
    for (size_t i = 0; i < points.size(); ++i) {
      Vec2 pixel;
      ASSERT_TRUE(c.Project(Vec3(points[i].x, points[i].y, points[i].z), &pixel));
      EXPECT_NEAR(pixel.x(), projected[i].x, 1e-6 * std::max(1.0, std::abs(pixel.x())));
      EXPECT_NEAR(pixel.y(), projected[i].y, 1e-6 * std::max(1.0, std::abs(pixel.y())));
    }
  }
}

// Where the models stop: a pinhole lens sees nothing at or behind 90
// degrees; a double-sphere lens nothing beyond its bound, and its image
// ends at r^2 = 1 / (2 alpha - 1) when alpha > 1/2.
TEST(CameraTest, PointsAndPixelsOutsideTheDomainAreRefused) {
  std::mt19937 rng(3);
  const Camera radtan = RandomLens(CameraModel::kPinholeRadTan, &rng);
  Vec2 pixel;
  EXPECT_FALSE(radtan.Project(Vec3(1, 0, 0), &pixel));
  EXPECT_FALSE(radtan.Project(Vec3(1, 2, -1), &pixel));
  Camera ds = RandomLens(CameraModel::kDoubleSphere, &rng);
  ds.k[DoubleSphere::kAlpha] = 0.7;
  const double theta = ds.MaxTheta();
  ASSERT_LT(theta, M_PI);
  EXPECT_FALSE(ds.Project(Vec3(std::sin(theta + 0.01), 0, std::cos(theta + 0.01)), &pixel));
  EXPECT_TRUE(ds.Project(Vec3(std::sin(theta - 0.01), 0, std::cos(theta - 0.01)), &pixel));
  const double r_end = 1 / std::sqrt(2 * 0.7 - 1);
  Vec3 bearing;
  EXPECT_FALSE(ds.Unproject(Vec2(ds.cx + 1.01 * r_end * ds.fx, ds.cy), &bearing));
}

// calibration.yaml keeps each camera's model and every parameter, and the
// radial-tangential D may come as OpenCV writes it, 4 or 5 long.
TEST(CameraTest, CalibrationYamlRoundTripKeepsEveryModel) {
  std::mt19937 rng(11);
  TempDir dir;
  for (CameraModel model :
       {CameraModel::kKannalaBrandt, CameraModel::kPinholeRadTan, CameraModel::kDoubleSphere}) {
    HelmetRig rig;
    rig.cameras.push_back({"cam0", RandomLens(model, &rng), Rigid3::Identity()});
    rig.cameras.push_back({"cam1", RandomLens(CameraModel::kKannalaBrandt, &rng),
                           Rigid3::Identity()});
    const auto path = dir.path() / "calibration.yaml";
    WriteCalibration(path, rig);
    const HelmetRig back = ReadCalibration(path);
    ASSERT_EQ(back.cameras.size(), 2u);
    for (int c = 0; c < 2; ++c) {
      EXPECT_EQ(back.cameras[c].camera.model, rig.cameras[c].camera.model);
      EXPECT_EQ(back.cameras[c].camera.Params(), rig.cameras[c].camera.Params())
          << CameraModelName(model);
    }
    if (model == CameraModel::kPinholeRadTan) {
      // OpenCV's 4-coefficient D: k3 = 0.
      std::string text = ReadFile(path);
      const size_t d = text.find("D: !!opencv-matrix", text.find("pinhole_radtan"));
      ASSERT_NE(d, std::string::npos);
      const size_t rows = text.find("rows: 5", d);
      text.replace(rows, 7, "rows: 4");
      const size_t data = text.find("data: [", d);
      const size_t last = text.rfind(',', text.find(']', data));
      text.erase(last, text.find(']', data) - last);
      WriteFileAtomic(path, text);
      const Camera four = ReadCalibration(path).cameras[0].camera;
      EXPECT_EQ(four.k[RadTan::kRadTanK3], 0.0);
      for (int i = 0; i < 4; ++i) EXPECT_EQ(four.k[i], rig.cameras[0].camera.k[i]);
    }
  }
}

// A D of the wrong length for the model, and a double-sphere alpha out of
// [0, 1], are refused naming the file, the camera and the model.
TEST(CameraTest, CalibrationYamlRefusesParametersThatDoNotFitTheModel) {
  std::mt19937 rng(13);
  TempDir dir;
  HelmetRig rig;
  rig.cameras.push_back({"upper", RandomLens(CameraModel::kKannalaBrandt, &rng), Rigid3::Identity()});
  const auto path = dir.path() / "calibration.yaml";
  WriteCalibration(path, rig);
  const std::string text = ReadFile(path);
  const auto expect_refused = [&](const std::string& changed, const std::string& model) {
    WriteFileAtomic(path, changed);
    try {
      ReadCalibration(path);
      ADD_FAILURE() << "accepted " << changed;
    } catch (const InputError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("calibration.yaml"), std::string::npos) << what;
      EXPECT_NE(what.find("upper"), std::string::npos) << what;
      EXPECT_NE(what.find(model), std::string::npos) << what;
    }
  };
  std::string ds = text;
  ds.replace(ds.find("model: kannala_brandt"), 21, "model: double_sphere");
  expect_refused(ds, "double_sphere");  // 4 numbers in D, not 2
  rig.cameras[0].camera = RandomLens(CameraModel::kDoubleSphere, &rng);
  rig.cameras[0].camera.k[DoubleSphere::kAlpha] = 1.5;
  WriteCalibration(path, rig);
  expect_refused(ReadFile(path), "double_sphere");
}

TEST(CameraTest, KalibrRoundTripKeepsEveryModel) {
  std::mt19937 rng(17);
  TempDir dir;
  HelmetRig rig;
  Rigid3 pose = Rigid3::Identity();
  for (CameraModel model :
       {CameraModel::kKannalaBrandt, CameraModel::kPinholeRadTan, CameraModel::kDoubleSphere}) {
    Camera c = RandomLens(model, &rng);
    if (model == CameraModel::kPinholeRadTan) c.k[RadTan::kRadTanK3] = 0;  // Kalibr has no k3
    pose.translation() += Vec3(0, -40, 5);
    rig.cameras.push_back({fmt::format("cam{}", rig.cameras.size()), c, pose});
  }
  const auto path = dir.path() / "camchain.yaml";
  WriteKalibrCamchain(path, rig);
  const std::string text = ReadFile(path);
  EXPECT_NE(text.find("distortion_model: radtan"), std::string::npos) << text;
  EXPECT_NE(text.find("camera_model: ds"), std::string::npos) << text;
  const std::vector<KalibrCamera> chain = ReadKalibrCamchain(path);
  ASSERT_EQ(chain.size(), 3u);
  for (size_t n = 0; n < chain.size(); ++n) {
    const Camera& a = rig.cameras[n].camera;
    const Camera& b = chain[n].camera;
    EXPECT_EQ(a.model, b.model);
    EXPECT_EQ(a.width, b.width);
    EXPECT_EQ(a.height, b.height);
    const auto pa = a.Params(), pb = b.Params();
    for (int i = 0; i < kNumCameraParams; ++i) {
      EXPECT_NEAR(pa[i], pb[i], 1e-12 * (1 + std::abs(pa[i]))) << CameraModelName(a.model) << i;
    }
  }
  // Kalibr's radtan has 4 coefficients: a lens with k3 cannot be written.
  rig.cameras[1].camera.k[RadTan::kRadTanK3] = 0.01;
  EXPECT_THROW(WriteKalibrCamchain(path, rig), InputError);
}

TEST(CameraTest, KalibrDoubleSphereReadsXiAndAlphaFirst) {
  TempDir dir;
  const auto path = dir.path() / "camchain.yaml";
  WriteFileAtomic(path,
                  "cam0:\n  camera_model: ds\n  distortion_model: none\n"
                  "  intrinsics: [-0.2, 0.6, 350.5, 351.5, 640.25, 511.75]\n"
                  "  distortion_coeffs: []\n  resolution: [1280, 1024]\n");
  const Camera c = ReadKalibrCamchain(path)[0].camera;
  EXPECT_EQ(c.model, CameraModel::kDoubleSphere);
  EXPECT_EQ(c.k[DoubleSphere::kXi], -0.2);
  EXPECT_EQ(c.k[DoubleSphere::kAlpha], 0.6);
  EXPECT_EQ(c.fx, 350.5);
  EXPECT_EQ(c.fy, 351.5);
  EXPECT_EQ(c.cx, 640.25);
  EXPECT_EQ(c.cy, 511.75);
}

}  // namespace
}  // namespace hmc
