#include "core/render_mesh.h"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "core/parallel.h"

namespace hmc {
namespace {

// A UV sphere, triangles counter-clockwise seen from outside.
TriMesh Sphere(const Vec3& center, double radius, int rings, int segments) {
  TriMesh mesh;
  const int n = (rings - 1) * segments + 2;
  mesh.V.resize(n, 3);
  mesh.V.row(0) = (center + Vec3(0, radius, 0)).transpose();
  mesh.V.row(n - 1) = (center - Vec3(0, radius, 0)).transpose();
  for (int r = 1; r < rings; ++r) {
    const double polar = M_PI * r / rings;
    for (int s = 0; s < segments; ++s) {
      const double azimuth = 2 * M_PI * s / segments;
      mesh.V.row(1 + (r - 1) * segments + s) =
          (center + radius * Vec3(std::sin(polar) * std::sin(azimuth),
                                  std::cos(polar),
                                  std::sin(polar) * std::cos(azimuth)))
              .transpose();
    }
  }
  std::vector<Eigen::Vector3i> faces;
  const auto at = [&](int r, int s) { return 1 + (r - 1) * segments + s % segments; };
  for (int s = 0; s < segments; ++s) {
    faces.emplace_back(0, at(1, s), at(1, s + 1));
    faces.emplace_back(n - 1, at(rings - 1, s + 1), at(rings - 1, s));
    for (int r = 1; r < rings - 1; ++r) {
      faces.emplace_back(at(r, s), at(r + 1, s), at(r + 1, s + 1));
      faces.emplace_back(at(r, s), at(r + 1, s + 1), at(r, s + 1));
    }
  }
  mesh.F.resize(faces.size(), 3);
  for (size_t f = 0; f < faces.size(); ++f) mesh.F.row(f) = faces[f].transpose();
  return mesh;
}

double MeanGrey(const cv::Mat& image, const cv::Rect& rect) {
  const cv::Scalar mean = cv::mean(image(rect));
  return (mean[0] + mean[1] + mean[2]) / 3;
}

// Outward normals point away from the centre: the sphere is wound as
// core/mesh.h says, so shading tests mean what they say.
TEST(RenderMesh, SphereFixtureIsWoundOutward) {
  const TriMesh sphere = Sphere(Vec3(1, 2, 3), 10, 12, 16);
  const MatX3d normals = VertexNormals(sphere.V, sphere.F);
  for (int v = 0; v < sphere.NumVertices(); ++v) {
    const Vec3 out = (sphere.V.row(v) - Eigen::RowVector3d(1, 2, 3)).normalized();
    EXPECT_GT(normals.row(v).dot(out), 0.95);
  }
}

TEST(RenderMesh, LitSideOfASphereIsBrighter) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> coord(-100, 100);
  for (const bool perspective : {true, false}) {
    const Vec3 center(coord(rng), coord(rng), coord(rng));
    const TriMesh sphere = Sphere(center, 40, 24, 32);
    MeshRenderOptions options;
    options.width = 96;
    options.height = 96;
    options.perspective = perspective;
    const cv::Mat image = RenderMesh(sphere, options);
    ASSERT_EQ(image.type(), CV_8UC3);
    ASSERT_EQ(image.rows, 96);
    ASSERT_EQ(image.cols, 96);
    // The key light is at the upper left, the fill at the right: the upper
    // left of the disc is brighter than the lower left, which gets neither.
    const double upper_left = MeanGrey(image, cv::Rect(24, 24, 12, 12));
    const double lower_left = MeanGrey(image, cv::Rect(24, 62, 12, 12));
    const double upper_right = MeanGrey(image, cv::Rect(62, 24, 12, 12));
    EXPECT_GT(upper_left, lower_left + 30) << perspective;
    EXPECT_GT(upper_left, upper_right) << perspective;
    // Corners are background (dark grey 0.15 -> 38), the centre is lit.
    const cv::Vec3b corner = image.at<cv::Vec3b>(0, 0);
    EXPECT_EQ(corner, cv::Vec3b(38, 38, 38));
    EXPECT_GT(MeanGrey(image, cv::Rect(44, 44, 8, 8)), 80);
  }
}

// Front view: the actor's left (+x) appears on the image's right; at a yaw
// of 90 degrees the camera looks from +x, so the +x half fills the view.
TEST(RenderMesh, ViewConventionsAndYaw) {
  const TriMesh sphere = Sphere(Vec3(0, 0, 0), 40, 24, 32);
  MatX3d colors(sphere.NumVertices(), 3);
  for (int v = 0; v < sphere.NumVertices(); ++v) {
    colors.row(v) = sphere.V(v, 0) > 0 ? Eigen::RowVector3d(0.9, 0.1, 0.1)
                                       : Eigen::RowVector3d(0.1, 0.1, 0.9);
  }
  MeshRenderOptions options;
  options.width = 80;
  options.height = 80;
  options.perspective = false;
  const cv::Mat front = RenderMesh(sphere, options, colors);
  const cv::Scalar right = cv::mean(front(cv::Rect(50, 30, 10, 20)));
  const cv::Scalar left = cv::mean(front(cv::Rect(20, 30, 10, 20)));
  EXPECT_GT(right[2], right[0] + 20);  // red (BGR) on the right
  EXPECT_GT(left[0], left[2] + 20);    // blue on the left

  options.yaw_deg = 90;
  const cv::Mat side = RenderMesh(sphere, options, colors);
  const cv::Scalar middle = cv::mean(side(cv::Rect(30, 30, 20, 20)));
  EXPECT_GT(middle[2], middle[0] + 20);
  options.yaw_deg = -90;
  const cv::Mat other = RenderMesh(sphere, options, colors);
  const cv::Scalar other_middle = cv::mean(other(cv::Rect(30, 30, 20, 20)));
  EXPECT_GT(other_middle[0], other_middle[2] + 20);
}

// The scalar path goes through the colour map: a field that is low on the
// left and high on the right shows the map's two ends there.
TEST(RenderMesh, ScalarFieldUsesTheColourMap) {
  const TriMesh sphere = Sphere(Vec3(0, 0, 0), 40, 16, 24);
  Eigen::VectorXd values = sphere.V.col(0);
  MeshRenderOptions options;
  options.width = 64;
  options.height = 64;
  const cv::Mat image =
      RenderMeshScalars(sphere, values, -40, 40, ColorMap::kCoolWarm, options);
  const cv::Scalar right = cv::mean(image(cv::Rect(42, 26, 8, 12)));
  const cv::Scalar left = cv::mean(image(cv::Rect(14, 26, 8, 12)));
  EXPECT_GT(right[2], right[0]);  // warm (red) for high values
  EXPECT_GT(left[0], left[2]);    // cool (blue) for low values
}

TEST(RenderMesh, DeterministicAcrossThreadCountsAndWireframeDarkens) {
  const TriMesh sphere = Sphere(Vec3(3, -2, 7), 25, 10, 14);
  MeshRenderOptions options;
  options.width = 64;
  options.height = 72;
  options.yaw_deg = 35;
  cv::Mat one;
  {
    ThreadLimit limit(1);
    one = RenderMesh(sphere, options);
  }
  const cv::Mat many = RenderMesh(sphere, options);
  EXPECT_EQ(cv::norm(one, many, cv::NORM_INF), 0);
  options.wireframe = true;
  const cv::Mat wire = RenderMesh(sphere, options);
  EXPECT_LT(cv::mean(wire)[1], cv::mean(one)[1]);
}

TEST(RenderMesh, OptionsCheck) {
  MeshRenderOptions options;
  EXPECT_TRUE(options.Check());
  options.width = 0;
  EXPECT_FALSE(options.Check());
  options = MeshRenderOptions();
  options.supersample = 0;
  EXPECT_FALSE(options.Check());
  options = MeshRenderOptions();
  options.pitch_deg = 95;
  EXPECT_FALSE(options.Check());
}

TEST(RenderMesh, LabelledPanelsSideBySide) {
  const cv::Mat a(50, 40, CV_8UC3, cv::Scalar(10, 20, 30));
  const cv::Mat b(50, 60, CV_8UC3, cv::Scalar(50, 60, 70));
  const cv::Mat out = ComposeLabelledPanels({a, b}, {"neutral", "smile"});
  EXPECT_EQ(out.cols, 100);
  EXPECT_GT(out.rows, 50);
  EXPECT_EQ(out.at<cv::Vec3b>(10, 10), cv::Vec3b(10, 20, 30));
  EXPECT_EQ(out.at<cv::Vec3b>(10, 70), cv::Vec3b(50, 60, 70));
  // Some label text was drawn in the strip below the first panel.
  double brightest = 0;
  cv::minMaxLoc(out(cv::Rect(0, 50, 40, out.rows - 50)).reshape(1), nullptr,
                &brightest);
  EXPECT_GT(brightest, 150);
}

}  // namespace
}  // namespace hmc
