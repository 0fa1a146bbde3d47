#include "core/mesh_metrics.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

namespace hmc {
namespace {

// A flat n x n grid of 1 mm squares in the z = 0 plane, two triangles each.
TriMesh Grid(int n) {
  TriMesh m;
  m.V.resize(n * n, 3);
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) m.V.row(j * n + i) << i, j, 0;
  }
  m.F.resize(2 * (n - 1) * (n - 1), 3);
  int t = 0;
  for (int j = 0; j + 1 < n; ++j) {
    for (int i = 0; i + 1 < n; ++i) {
      const int a = j * n + i, b = a + 1, c = a + n, d = c + 1;
      m.F.row(t++) << a, b, d;
      m.F.row(t++) << a, d, c;
    }
  }
  return m;
}

class MetricsSeeded : public ::testing::TestWithParam<int> {};

TEST_P(MetricsSeeded, VertexErrorsAndResidualsAgreeWithBruteForce) {
  std::mt19937 rng(GetParam());
  std::normal_distribution<double> noise(0, 1);
  const TriMesh m = Grid(6);
  MatX3d a = m.V, b = m.V;
  for (int i = 0; i < a.rows(); ++i) {
    for (int c = 0; c < 3; ++c) b(i, c) += noise(rng);
  }
  const Eigen::VectorXd e = VertexErrors(a, b);
  for (int i = 0; i < a.rows(); ++i) {
    const double dx = a(i, 0) - b(i, 0), dy = a(i, 1) - b(i, 1),
                 dz = a(i, 2) - b(i, 2);
    EXPECT_NEAR(e[i], std::sqrt(dx * dx + dy * dy + dz * dz), 1e-12);
  }
  std::uniform_int_distribution<int> face(0, m.NumFaces() - 1);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<SurfacePoint> sites(7);
  MatX3d targets(7, 3);
  for (int k = 0; k < 7; ++k) {
    sites[k].face = face(rng);
    double x = u(rng), y = u(rng) * (1 - x);
    sites[k].bary = Vec3(x, y, 1 - x - y);
    targets.row(k) = (EvaluateSurfacePoint(sites[k], m.F, a) +
                      Vec3(noise(rng), noise(rng), noise(rng)))
                         .transpose();
  }
  targets.row(3).setConstant(std::nan(""));  // a marker without a target
  const std::vector<double> r = BundleResiduals(m.F, sites, b, targets);
  ASSERT_EQ(r.size(), 6u);
  int j = 0;
  for (int k = 0; k < 7; ++k) {
    if (k == 3) continue;
    Vec3 x = Vec3::Zero();
    for (int i = 0; i < 3; ++i) {
      x += sites[k].bary[i] * b.row(m.F(sites[k].face, i)).transpose();
    }
    EXPECT_NEAR(r[j++], (x - targets.row(k).transpose()).norm(), 1e-12);
  }
}

TEST_P(MetricsSeeded, FaceRegionIsTheVerticesNearAMarker) {
  std::mt19937 rng(GetParam());
  const TriMesh m = Grid(15);
  std::uniform_int_distribution<int> vertex(0, m.NumVertices() - 1);
  std::vector<SurfacePoint> sites;
  std::vector<int> site_vertices;
  for (int k = 0; k < 3; ++k) {
    site_vertices.push_back(vertex(rng));
    sites.push_back(SurfacePointAtVertex(m.F, site_vertices.back()));
  }
  for (double radius : {0.5, 2.5, 4.0}) {
    const std::vector<uint8_t> mask = FaceRegionMask(m, sites, radius);
    for (int v = 0; v < m.NumVertices(); ++v) {
      // Integer grid: distance between vertices from their indices.
      bool near = false;
      for (int s : site_vertices) {
        const int dx = v % 15 - s % 15, dy = v / 15 - s / 15;
        near |= std::sqrt(double(dx * dx + dy * dy)) <= radius + 1e-9;
      }
      EXPECT_EQ(mask[v] != 0, near) << "vertex " << v << " radius " << radius;
    }
  }
}

TEST(UniformLaplacian, AnnihilatesConstantsAndAffineOnTheInterior) {
  const int n = 8;
  const TriMesh m = Grid(n);
  const Eigen::SparseMatrix<double> L = UniformLaplacian(m.F, m.NumVertices());
  const Eigen::VectorXd ones = Eigen::VectorXd::Ones(m.NumVertices());
  EXPECT_LT((L * ones).norm(), 1e-12);
  // An affine field is reproduced by the neighbour mean on interior vertices
  // of this grid (its one-ring is centrally symmetric).
  Eigen::MatrixXd affine = m.V * Eigen::Matrix3d::Random();
  const Eigen::MatrixXd delta = L * affine;
  for (int j = 1; j + 1 < n; ++j) {
    for (int i = 1; i + 1 < n; ++i) {
      EXPECT_LT(delta.row(j * n + i).norm(), 1e-12);
    }
  }
}

TEST_P(MetricsSeeded, DetailErrorSeesHighFrequenciesNotSmoothOffsets) {
  std::mt19937 rng(GetParam());
  const int n = 30;
  const TriMesh m = Grid(n);
  const Eigen::SparseMatrix<double> L = UniformLaplacian(m.F, m.NumVertices());
  auto mean = [](const Eigen::VectorXd& x) { return x.mean(); };
  // Identical meshes and translations: exactly zero.
  EXPECT_EQ(DetailErrors(L, m.V, m.V).maxCoeff(), 0.0);
  MatX3d shifted = m.V;
  shifted.rowwise() += Eigen::RowVector3d(3, -2, 5);
  EXPECT_LT(DetailErrors(L, m.V, shifted).maxCoeff(), 1e-12);

  const double amplitude = 0.5;  // mm
  std::uniform_real_distribution<double> u(-1, 1);
  MatX3d noisy = m.V, smooth = m.V;
  const double phase = u(rng) * M_PI;
  for (int v = 0; v < m.NumVertices(); ++v) {
    noisy(v, 2) += amplitude * u(rng);
    // One period over the grid: a smooth bulge of the same amplitude.
    smooth(v, 2) += amplitude * std::sin(2 * M_PI * m.V(v, 0) / n + phase);
  }
  MatX3d noisier = m.V;
  noisier.col(2) = m.V.col(2) + 2 * (noisy.col(2) - m.V.col(2));
  const double e_noise = mean(DetailErrors(L, m.V, noisy));
  const double e_noisier = mean(DetailErrors(L, m.V, noisier));
  const double e_smooth = mean(DetailErrors(L, m.V, smooth));
  EXPECT_GT(e_noise, 0.1 * amplitude);
  EXPECT_NEAR(e_noisier, 2 * e_noise, 1e-9);  // linear in the difference
  // Second difference of a sine with period n: amplitude (2 pi / n)^2 / 2
  // at most on the interior, far below the noise's.
  EXPECT_LT(e_smooth, 0.1 * e_noise);
}

INSTANTIATE_TEST_SUITE_P(Seeds, MetricsSeeded, ::testing::Values(1, 2, 3, 7));

}  // namespace
}  // namespace hmc
