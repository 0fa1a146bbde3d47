#include "core/camera.h"

#include <cmath>
#include <random>
#include <vector>

#include <ceres/jet.h>
#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>

#include "core/error.h"

namespace hmc {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDegToRad = kPi / 180.0;

// A random lens of `max_fov_deg` total field of view whose polynomial is
// one-to-one over the whole field (plus a margin), like a real 220-degree
// fisheye: small random k1..k4 and a focal length that maps the edge of the
// field close to the edge of the image.
FisheyeCamera RandomLens(std::mt19937* rng, double max_fov_deg) {
  std::uniform_real_distribution<double> k1(-0.05, 0.05);
  std::uniform_real_distribution<double> k2(-0.01, 0.01);
  std::uniform_real_distribution<double> k3(-0.003, 0.003);
  std::uniform_real_distribution<double> k4(-0.0005, 0.0005);
  std::uniform_real_distribution<double> jitter(-20.0, 20.0);
  const double half_fov = 0.5 * max_fov_deg * kDegToRad;
  for (;;) {
    FisheyeCamera camera;
    camera.width = 1280;
    camera.height = 1024;
    camera.k = {k1(*rng), k2(*rng), k3(*rng), k4(*rng)};
    if (camera.MaxTheta() < half_fov + 0.05) continue;
    const double theta_d =
        half_fov * (1 + std::pow(half_fov, 2) * camera.k[0] +
                    std::pow(half_fov, 4) * camera.k[1] +
                    std::pow(half_fov, 6) * camera.k[2] +
                    std::pow(half_fov, 8) * camera.k[3]);
    camera.fx = 500.0 / theta_d + jitter(*rng);
    camera.fy = camera.fx * (1.0 + 0.01 * jitter(*rng) / 20.0);
    camera.cx = 639.5 + jitter(*rng);
    camera.cy = 511.5 + jitter(*rng);
    return camera;
  }
}

// A point at angle `theta` off the optical axis, azimuth `phi`, distance `d`.
Vec3 PointAt(double theta, double phi, double d) {
  return d * Vec3(std::sin(theta) * std::cos(phi),
                  std::sin(theta) * std::sin(phi), std::cos(theta));
}

double AngleBetween(const Vec3& a, const Vec3& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b));
}

class FisheyeSeeded : public ::testing::TestWithParam<int> {};

TEST_P(FisheyeSeeded, PointRoundTripUpTo110Degrees) {
  std::mt19937 rng(GetParam());
  std::uniform_real_distribution<double> theta_deg(0.0, 110.0);
  std::uniform_real_distribution<double> phi(-kPi, kPi);
  std::uniform_real_distribution<double> distance(5.0, 2000.0);
  int beyond_90 = 0;
  for (int lens = 0; lens < 5; ++lens) {
    const FisheyeCamera camera = RandomLens(&rng, 220.0);
    for (int i = 0; i < 2000; ++i) {
      const double theta = theta_deg(rng) * kDegToRad;
      const Vec3 point = PointAt(theta, phi(rng), distance(rng));
      Vec2 pixel;
      ASSERT_TRUE(camera.Project(point, &pixel)) << point.transpose();
      Vec3 bearing;
      ASSERT_TRUE(camera.Unproject(pixel, &bearing)) << pixel.transpose();
      EXPECT_NEAR(bearing.norm(), 1.0, 1e-12);
      EXPECT_LT(AngleBetween(bearing, point), 1e-9)
          << "theta " << theta / kDegToRad << " deg";
      if (point.z() <= 0) ++beyond_90;
    }
  }
  EXPECT_GT(beyond_90, 1000);  // ~18% of 10000 lie beyond 90 degrees
}

TEST_P(FisheyeSeeded, PixelRoundTripOverTheImageCircle) {
  std::mt19937 rng(GetParam() + 100);
  for (int lens = 0; lens < 5; ++lens) {
    const FisheyeCamera camera = RandomLens(&rng, 220.0);
    // theta_d of the field's edge (110 degrees) bounds the image circle.
    Vec2 edge;
    ASSERT_TRUE(camera.Project(PointAt(110 * kDegToRad, 0.0, 1.0), &edge));
    const double radius_px = edge.x() - camera.cx;
    std::uniform_real_distribution<double> unit(-1.0, 1.0);
    for (int i = 0; i < 2000; ++i) {
      Vec2 offset(unit(rng), unit(rng));
      if (offset.norm() > 1.0) continue;
      const Vec2 pixel(camera.cx + radius_px * offset.x(),
                       camera.cy + radius_px * offset.y() * camera.fy /
                                       camera.fx);
      Vec3 bearing;
      ASSERT_TRUE(camera.Unproject(pixel, &bearing)) << pixel.transpose();
      Vec2 back;
      ASSERT_TRUE(camera.Project(bearing * 37.0, &back));
      EXPECT_LT((back - pixel).norm(), 1e-6) << pixel.transpose();
    }
  }
}

// d pixel / d (intrinsics, point) from ceres::Jet against central finite
// differences, over the whole field including the axis and beyond 90 deg.
TEST_P(FisheyeSeeded, JetJacobianMatchesFiniteDifferences) {
  constexpr int kN = kNumFisheyeParams + 3;
  using Jet = ceres::Jet<double, kN>;
  std::mt19937 rng(GetParam() + 200);
  std::uniform_real_distribution<double> theta_deg(0.0, 108.0);
  std::uniform_real_distribution<double> phi(-kPi, kPi);
  std::uniform_real_distribution<double> distance(10.0, 1000.0);
  for (int i = 0; i < 300; ++i) {
    const FisheyeCamera camera = RandomLens(&rng, 220.0);
    const double theta = i < 5 ? 0.0 : theta_deg(rng) * kDegToRad;
    const Vec3 point = PointAt(theta, phi(rng), distance(rng));
    const auto params = camera.Params();
    double x[kN];
    for (int j = 0; j < kNumFisheyeParams; ++j) x[j] = params[j];
    for (int j = 0; j < 3; ++j) x[kNumFisheyeParams + j] = point[j];

    Jet jets[kN];
    for (int j = 0; j < kN; ++j) jets[j] = Jet(x[j], j);
    Jet pixel[2];
    ASSERT_TRUE(KannalaBrandt::Project(jets, jets + kNumFisheyeParams, pixel));

    for (int j = 0; j < kN; ++j) {
      const double h = 1e-6 * std::max(1.0, std::abs(x[j]));
      double plus[kN];
      double minus[kN];
      std::copy(x, x + kN, plus);
      std::copy(x, x + kN, minus);
      plus[j] += h;
      minus[j] -= h;
      double p_plus[2];
      double p_minus[2];
      ASSERT_TRUE(KannalaBrandt::Project(plus, plus + kNumFisheyeParams,
                                         p_plus));
      ASSERT_TRUE(KannalaBrandt::Project(minus, minus + kNumFisheyeParams,
                                         p_minus));
      for (int c = 0; c < 2; ++c) {
        const double numeric = (p_plus[c] - p_minus[c]) / (2 * h);
        const double analytic = pixel[c].v[j];
        EXPECT_NEAR(analytic, numeric, 1e-5 * std::max(1.0, std::abs(numeric)))
            << "row " << c << " column " << j << " theta "
            << theta / kDegToRad;
      }
    }
  }
}

TEST_P(FisheyeSeeded, AgreesWithOpenCvInFront) {
  std::mt19937 rng(GetParam() + 300);
  std::uniform_real_distribution<double> theta_deg(0.0, 85.0);
  std::uniform_real_distribution<double> phi(-kPi, kPi);
  std::uniform_real_distribution<double> distance(10.0, 1000.0);
  const FisheyeCamera camera = RandomLens(&rng, 200.0);
  std::vector<cv::Point3d> points;
  for (int i = 0; i < 1000; ++i) {
    const Vec3 p = PointAt(theta_deg(rng) * kDegToRad, phi(rng), distance(rng));
    points.emplace_back(p.x(), p.y(), p.z());
  }
  std::vector<cv::Point2d> expected;
  cv::fisheye::projectPoints(points, expected, cv::Vec3d(0, 0, 0),
                             cv::Vec3d(0, 0, 0), camera.K(), camera.D());
  for (size_t i = 0; i < points.size(); ++i) {
    Vec2 pixel;
    ASSERT_TRUE(
        camera.Project(Vec3(points[i].x, points[i].y, points[i].z), &pixel));
    EXPECT_NEAR(pixel.x(), expected[i].x, 1e-8);
    EXPECT_NEAR(pixel.y(), expected[i].y, 1e-8);
  }
}

// Where cv::fisheye::undistortPoints is reliable (well inside 90 degrees),
// our unprojection gives the same rays.
TEST_P(FisheyeSeeded, UnprojectAgreesWithOpenCvWellInsideTheField) {
  std::mt19937 rng(GetParam() + 400);
  std::uniform_real_distribution<double> theta_deg(0.0, 60.0);
  std::uniform_real_distribution<double> phi(-kPi, kPi);
  const FisheyeCamera camera = RandomLens(&rng, 200.0);
  std::vector<cv::Point2d> pixels;
  std::vector<Vec3> truth;
  for (int i = 0; i < 500; ++i) {
    truth.push_back(PointAt(theta_deg(rng) * kDegToRad, phi(rng), 1.0));
    Vec2 pixel;
    ASSERT_TRUE(camera.Project(truth.back(), &pixel));
    pixels.emplace_back(pixel.x(), pixel.y());
  }
  std::vector<cv::Point2d> normalized;
  cv::fisheye::undistortPoints(
      pixels, normalized, camera.K(), camera.D(), cv::noArray(), cv::noArray(),
      cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 100,
                       1e-14));
  for (size_t i = 0; i < pixels.size(); ++i) {
    Vec3 bearing;
    ASSERT_TRUE(camera.Unproject(Vec2(pixels[i].x, pixels[i].y), &bearing));
    const Vec3 opencv = Vec3(normalized[i].x, normalized[i].y, 1.0).normalized();
    EXPECT_LT(AngleBetween(bearing, opencv), 1e-7);
    EXPECT_LT(AngleBetween(bearing, truth[i]), 1e-9);
  }
}

INSTANTIATE_TEST_SUITE_P(Seeds, FisheyeSeeded, ::testing::Values(1, 7, 42));

TEST(Fisheye, OnAxisProjectsToThePrincipalPoint) {
  std::mt19937 rng(3);
  const FisheyeCamera camera = RandomLens(&rng, 220.0);
  Vec2 pixel;
  ASSERT_TRUE(camera.Project(Vec3(0, 0, 250.0), &pixel));
  EXPECT_DOUBLE_EQ(pixel.x(), camera.cx);
  EXPECT_DOUBLE_EQ(pixel.y(), camera.cy);
  Vec3 bearing;
  ASSERT_TRUE(camera.Unproject(Vec2(camera.cx, camera.cy), &bearing));
  EXPECT_EQ(bearing, Vec3(0, 0, 1));
  // Straight behind and the origin have no image.
  EXPECT_FALSE(camera.Project(Vec3(0, 0, -5.0), &pixel));
  EXPECT_FALSE(camera.Project(Vec3(0, 0, 0), &pixel));
}

// A lens whose polynomial turns over: theta_d(theta) peaks at MaxTheta().
// Beyond it neither direction is defined, and Unproject reports failure
// for a theta_d above the peak instead of returning a wrong ray.
TEST(Fisheye, ReportsAnglesOutsideTheMonotonicRange) {
  FisheyeCamera camera;
  camera.width = 1000;
  camera.height = 1000;
  camera.fx = camera.fy = 300;
  camera.cx = camera.cy = 499.5;
  camera.k = {-0.12, 0.0, 0.0, 0.0};
  // Slope 1 - 0.36 theta^2 vanishes at theta = 1 / 0.6.
  const double theta_max = 1.0 / 0.6;
  EXPECT_NEAR(camera.MaxTheta(), theta_max, 1e-12);
  const double peak = theta_max * (1 - 0.12 * theta_max * theta_max);

  Vec3 bearing;
  // Just inside the range: a ray, and it projects back.
  const Vec2 inside(camera.cx + camera.fx * (peak - 1e-6), camera.cy);
  ASSERT_TRUE(camera.Unproject(inside, &bearing));
  Vec2 back;
  ASSERT_TRUE(camera.Project(bearing, &back));
  EXPECT_LT((back - inside).norm(), 1e-6);
  // Above the peak: no angle maps there.
  EXPECT_FALSE(
      camera.Unproject(Vec2(camera.cx + camera.fx * (peak + 1e-6), camera.cy),
                       &bearing));
  EXPECT_FALSE(camera.Unproject(Vec2(1e6, -1e6), &bearing));
  EXPECT_FALSE(camera.Unproject(Vec2(NAN, 0), &bearing));
  // Points beyond the turning angle do not project.
  Vec2 pixel;
  EXPECT_TRUE(camera.Project(PointAt(theta_max - 1e-3, 0.3, 1.0), &pixel));
  EXPECT_FALSE(camera.Project(PointAt(theta_max + 1e-3, 0.3, 1.0), &pixel));
}

TEST(Fisheye, OpenCvMatricesRoundTrip) {
  std::mt19937 rng(11);
  const FisheyeCamera camera = RandomLens(&rng, 200.0);
  const FisheyeCamera back = FisheyeCamera::FromOpenCv(
      cv::Mat(camera.K()), cv::Mat(camera.D()),
      cv::Size(camera.width, camera.height));
  EXPECT_EQ(back.Params(), camera.Params());
  EXPECT_EQ(back.width, camera.width);
  EXPECT_EQ(back.height, camera.height);
  // D as a row vector of floats is accepted too.
  cv::Mat d_row(1, 4, CV_32F);
  for (int i = 0; i < 4; ++i) d_row.at<float>(0, i) = static_cast<float>(camera.k[i]);
  const FisheyeCamera from_float = FisheyeCamera::FromOpenCv(
      cv::Mat(camera.K()), d_row, cv::Size(camera.width, camera.height));
  EXPECT_EQ(from_float.k[2], static_cast<float>(camera.k[2]));

  EXPECT_THROW(FisheyeCamera::FromOpenCv(cv::Mat::eye(2, 3, CV_64F),
                                         cv::Mat(camera.D()), cv::Size(1, 1)),
               InputError);
  EXPECT_THROW(FisheyeCamera::FromOpenCv(cv::Mat(camera.K()),
                                         cv::Mat::zeros(5, 1, CV_64F),
                                         cv::Size(1, 1)),
               InputError);
  cv::Mat skewed(camera.K());
  skewed.at<double>(0, 1) = 0.5;
  EXPECT_THROW(FisheyeCamera::FromOpenCv(skewed, cv::Mat(camera.D()),
                                         cv::Size(1, 1)),
               InputError);
}

TEST(Fisheye, IsInImageUsesPixelCentres) {
  FisheyeCamera camera;
  camera.width = 4;
  camera.height = 3;
  EXPECT_TRUE(camera.IsInImage(Vec2(-0.5, -0.5)));
  EXPECT_TRUE(camera.IsInImage(Vec2(3.49, 2.49)));
  EXPECT_FALSE(camera.IsInImage(Vec2(3.5, 1.0)));
  EXPECT_FALSE(camera.IsInImage(Vec2(1.0, -0.51)));
}

}  // namespace
}  // namespace hmc
