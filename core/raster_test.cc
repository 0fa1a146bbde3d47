#include "core/raster.h"

#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "core/parallel.h"

namespace hmc {
namespace {

// A triangulated grid covering the square [-0.5, size - 0.5]^2, whose
// interior vertices are jittered; with `snap`, they sit exactly on pixel
// centres or on half-pixel lines, so many pixel centres fall exactly on
// shared edges and vertices (the fill-rule cases). Diagonals alternate.
void TiledSquare(int size, int cells, bool snap, std::mt19937* rng,
                 MatX3d* V, MatX3i* F) {
  std::uniform_real_distribution<double> jitter(-0.35, 0.35);
  const int n = cells + 1;
  V->resize(n * n, 3);
  const double cell = static_cast<double>(size) / cells;
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      double x = -0.5 + i * cell;
      double y = -0.5 + j * cell;
      if (i > 0 && i < cells && j > 0 && j < cells) {
        x += jitter(*rng) * cell;
        y += jitter(*rng) * cell;
        if (snap) {
          x = std::round(x * 2) / 2;
          y = std::round(y * 2) / 2;
        }
      }
      V->row(j * n + i) << x, y, 1.0;
    }
  }
  F->resize(2 * cells * cells, 3);
  int f = 0;
  for (int j = 0; j < cells; ++j) {
    for (int i = 0; i < cells; ++i) {
      const int a = j * n + i, b = a + 1, c = a + n, d = c + 1;
      if ((i + j) % 2 == 0) {
        F->row(f++) << a, b, d;
        F->row(f++) << a, d, c;
      } else {
        F->row(f++) << a, b, c;
        F->row(f++) << b, d, c;
      }
    }
  }
}

// Coverage count per pixel, by visiting every triangle with the low-level
// coverage loop (no z-buffer hiding double hits).
std::vector<int> CoverageCount(const MatX3d& V, const MatX3i& F, int width,
                               int height) {
  std::vector<int> count(width * height, 0);
  for (int t = 0; t < F.rows(); ++t) {
    double x[3], y[3];
    for (int i = 0; i < 3; ++i) {
      x[i] = V(F(t, i), 0);
      y[i] = V(F(t, i), 1);
    }
    TriangleSetup setup;
    if (!SetupTriangle(x, y, CullMode::kNone, &setup)) continue;
    ForEachCoveredPixel(setup, 0, 0, width - 1, height - 1,
                        [&](int px, int py, const int64_t*) {
                          ++count[py * width + px];
                        });
  }
  return count;
}

class RasterSeeded : public ::testing::TestWithParam<int> {};

TEST_P(RasterSeeded, TiledSquareCoversEveryPixelExactlyOnce) {
  std::mt19937 rng(GetParam());
  for (const bool snap : {false, true}) {
    for (const int cells : {3, 8, 17}) {
      MatX3d V;
      MatX3i F;
      const int size = 48;
      TiledSquare(size, cells, snap, &rng, &V, &F);
      // Flip the winding of a random half: coverage must not depend on it.
      for (int t = 0; t < F.rows(); ++t) {
        if (rng() % 2) std::swap(F(t, 1), F(t, 2));
      }
      const std::vector<int> count = CoverageCount(V, F, size, size);
      for (int p = 0; p < size * size; ++p) {
        ASSERT_EQ(count[p], 1) << "pixel (" << p % size << ", " << p / size
                               << ") snap " << snap << " cells " << cells;
      }
      // The tiled, parallel rasterizer agrees.
      RasterOptions options;
      options.width = size;
      options.height = size;
      options.tile_size = 8;
      const RasterBuffer buffer = Rasterize(V, Eigen::VectorXd(), F, options);
      EXPECT_EQ(buffer.NumCovered(), size * size);
    }
  }
}

// A fan around a centre that sits exactly on a pixel centre: the centre
// pixel belongs to exactly one of the many triangles meeting there.
TEST_P(RasterSeeded, FanAroundAPixelCentreCoversItOnce) {
  std::mt19937 rng(GetParam());
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const int n = 5 + static_cast<int>(rng() % 8);
  std::vector<double> angles(n);
  for (int i = 0; i < n; ++i) angles[i] = 2 * M_PI * (i + 0.8 * unit(rng)) / n;
  MatX3d V(n + 1, 3);
  V.row(0) << 10, 10, 0;
  for (int i = 0; i < n; ++i) {
    // Some spokes snapped to pixel centres, so edges pass through centres.
    double x = 10 + 8 * std::cos(angles[i]);
    double y = 10 + 8 * std::sin(angles[i]);
    if (i % 2) {
      x = std::round(x);
      y = std::round(y);
    }
    V.row(i + 1) << x, y, 0;
  }
  MatX3i F(n, 3);
  for (int i = 0; i < n; ++i) F.row(i) << 0, 1 + i, 1 + (i + 1) % n;
  const std::vector<int> count = CoverageCount(V, F, 21, 21);
  EXPECT_EQ(count[10 * 21 + 10], 1);
  for (int c : count) EXPECT_LE(c, 1);
}

TEST_P(RasterSeeded, NearestTriangleWinsTheDepthTest) {
  std::mt19937 rng(GetParam());
  std::uniform_real_distribution<double> depth(1.0, 100.0);
  // Random overlapping triangles that each cover the whole 16 x 16 image.
  const int num = 12;
  MatX3d V(3 * num, 3);
  MatX3i F(num, 3);
  std::vector<double> depths(num);
  for (int t = 0; t < num; ++t) {
    depths[t] = depth(rng);
    V.row(3 * t) << -10, -10, depths[t];
    V.row(3 * t + 1) << 60, -10, depths[t];
    V.row(3 * t + 2) << -10, 60, depths[t];
    F.row(t) << 3 * t, 3 * t + 1, 3 * t + 2;
  }
  const int nearest =
      static_cast<int>(std::min_element(depths.begin(), depths.end()) -
                       depths.begin());
  RasterOptions options;
  options.width = 16;
  options.height = 16;
  const RasterBuffer buffer = Rasterize(V, Eigen::VectorXd(), F, options);
  for (int p = 0; p < 256; ++p) {
    ASSERT_EQ(buffer.triangle[p], nearest);
    EXPECT_DOUBLE_EQ(buffer.depth[p], depths[nearest]);
  }

  // Two triangles crossing in depth: each pixel shows the one nearer there.
  MatX3d W(6, 3);
  W << -1, -1, 10, 40, -1, 10, -1, 16.5, 30,   // depth grows with y
       -1, -1, 30, 40, -1, 30, -1, 16.5, 10;   // depth falls with y
  MatX3i G(2, 3);
  G << 0, 1, 2, 3, 4, 5;
  const RasterBuffer crossing = Rasterize(W, Eigen::VectorXd(), G, options);
  int seen[2] = {0, 0};
  for (int y = 0; y < 14; ++y) {  // both cover (3, y) for y <= 14
    const double d0 = 10 + 20.0 * (y + 1) / 17.5;
    const double d1 = 30 - 20.0 * (y + 1) / 17.5;
    ++seen[d0 <= d1 ? 0 : 1];
    const int index = crossing.Index(3, y);
    EXPECT_EQ(crossing.triangle[index], d0 <= d1 ? 0 : 1) << y;
    EXPECT_NEAR(crossing.depth[index], std::min(d0, d1), 1e-9);
  }
  EXPECT_GT(seen[0], 3);
  EXPECT_GT(seen[1], 3);
}

// A fan of triangles around a vertex on a pixel centre: whichever triangle
// owns that pixel, the interpolated attribute and depth equal the vertex's
// own exactly (bitwise), also with perspective weights.
TEST_P(RasterSeeded, AttributesAreExactAtVertices) {
  std::mt19937 rng(GetParam());
  std::uniform_real_distribution<double> value(-5.0, 5.0);
  std::uniform_real_distribution<double> depth(10.0, 500.0);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int trial = 0; trial < 30; ++trial) {
    const int n = 4 + static_cast<int>(rng() % 6);  // gaps < 180 deg
    const int cx = 8 + static_cast<int>(rng() % 16);
    const int cy = 8 + static_cast<int>(rng() % 16);
    MatX3d V(n + 1, 3);
    Eigen::VectorXd inv_w(n + 1);
    Eigen::MatrixXd attribute(n + 1, 4);
    for (int i = 0; i <= n; ++i) {
      const double angle = 2 * M_PI * (i - 1 + 0.8 * unit(rng)) / n;
      const double r = 3 + 4 * unit(rng);
      const double z = depth(rng);
      if (i == 0) {
        V.row(i) << cx, cy, z;
      } else {
        V.row(i) << cx + r * std::cos(angle), cy + r * std::sin(angle), z;
      }
      inv_w[i] = 1.0 / z;
      for (int k = 0; k < 4; ++k) attribute(i, k) = value(rng);
    }
    MatX3i F(n, 3);
    for (int i = 0; i < n; ++i) F.row(i) << 1 + i, 0, 1 + (i + 1) % n;
    RasterOptions options;
    options.width = 32;
    options.height = 32;
    for (const bool perspective : {false, true}) {
      const RasterBuffer buffer =
          Rasterize(V, perspective ? inv_w : Eigen::VectorXd(), F, options);
      const int index = buffer.Index(cx, cy);
      ASSERT_TRUE(buffer.Covered(index));
      const Eigen::RowVectorXd at = InterpolateAt(buffer, index, F, attribute);
      EXPECT_EQ(at, attribute.row(0));
      EXPECT_EQ(buffer.depth[index], V(0, 2));
    }
  }
}

// Perspective correctness: a pixel's interpolated attribute equals the
// attribute at the 3D point that projects there. With camera depth z_i and
// screen barycentrics s_i, that point has weights (s_i / z_i) normalised (a
// pinhole camera maps planes to planes), and its depth is 1 / sum s_i / z_i.
TEST_P(RasterSeeded, AttributesArePerspectiveCorrect) {
  std::mt19937 rng(GetParam());
  std::uniform_real_distribution<double> coord(-10.0, 74.0);
  std::uniform_real_distribution<double> value(-5.0, 5.0);
  std::uniform_real_distribution<double> depth(10.0, 500.0);
  int checked = 0;
  for (int trial = 0; trial < 20; ++trial) {
    MatX3d V(3, 3);
    Eigen::VectorXd inv_w(3);
    Eigen::MatrixXd attribute(3, 4);
    for (int i = 0; i < 3; ++i) {
      const double z = depth(rng);
      V.row(i) << coord(rng), coord(rng), z;
      inv_w[i] = 1.0 / z;
      for (int k = 0; k < 4; ++k) attribute(i, k) = value(rng);
    }
    MatX3i F(1, 3);
    F << 0, 1, 2;
    RasterOptions options;
    options.width = 64;
    options.height = 64;
    const RasterBuffer buffer = Rasterize(V, inv_w, F, options);
    double x[3] = {V(0, 0), V(1, 0), V(2, 0)};
    double y[3] = {V(0, 1), V(1, 1), V(2, 1)};
    TriangleSetup setup;
    if (!SetupTriangle(x, y, CullMode::kNone, &setup)) continue;
    for (int index = 0; index < 64 * 64; ++index) {
      if (!buffer.Covered(index)) continue;
      int64_t w[3];
      setup.EdgesAt(index % 64, index / 64, w);
      Eigen::Vector3d s(w[0], w[1], w[2]);
      s /= static_cast<double>(setup.area2);
      Eigen::Vector3d b = s.cwiseProduct(inv_w);
      b /= b.sum();
      EXPECT_NEAR(buffer.depth[index], 1.0 / s.dot(inv_w), 1e-9);
      EXPECT_LT((InterpolateAt(buffer, index, F, attribute).transpose() -
                 attribute.transpose() * b).norm(), 1e-12);
      ++checked;
    }
  }
  EXPECT_GT(checked, 1000);
}

TEST_P(RasterSeeded, SameResultWhateverTheThreadCount) {
  std::mt19937 rng(GetParam());
  std::uniform_real_distribution<double> pos(-20.0, 220.0);
  std::uniform_real_distribution<double> depth(1.0, 10.0);
  const int num = 400;
  MatX3d V(3 * num, 3);
  MatX3i F(num, 3);
  for (int t = 0; t < num; ++t) {
    const double z = depth(rng);  // many equal depths: ties must be stable
    for (int i = 0; i < 3; ++i) V.row(3 * t + i) << pos(rng), pos(rng), z;
    F.row(t) << 3 * t, 3 * t + 1, 3 * t + 2;
  }
  for (int t = 0; t < num; t += 2) V(3 * t, 2) = V(3 * t + 1, 2) = V(3 * t + 2, 2) = 5.0;
  RasterOptions options;
  options.width = 200;
  options.height = 150;
  options.tile_size = 16;
  RasterBuffer one;
  {
    ThreadLimit limit(1);
    one = Rasterize(V, Eigen::VectorXd(), F, options);
  }
  RasterBuffer many;
  {
    ThreadLimit limit(4);
    many = Rasterize(V, Eigen::VectorXd(), F, options);
  }
  EXPECT_EQ(one.triangle, many.triangle);
  EXPECT_EQ(one.depth, many.depth);
  // The tile size is a scheduling detail, not a result.
  options.tile_size = 64;
  const RasterBuffer coarse = Rasterize(V, Eigen::VectorXd(), F, options);
  EXPECT_EQ(one.triangle, coarse.triangle);
  EXPECT_GT(one.NumCovered(), 1000);
}

// The id-only rasterizer reports exactly the triangles of the full buffer
// (same depth arithmetic, tile-local z-buffer), with and without
// perspective weights, whatever the thread count and tile size.
TEST_P(RasterSeeded, TriangleIdsMatchTheFullBuffer) {
  std::mt19937 rng(GetParam() + 1000);
  std::uniform_real_distribution<double> pos(-30.0, 250.0);
  std::uniform_real_distribution<double> depth(1.0, 10.0);
  const int num = 300;
  MatX3d V(3 * num, 3);
  MatX3i F(num, 3);
  Eigen::VectorXd inv_w(3 * num);
  for (int t = 0; t < num; ++t) {
    const double z = depth(rng);
    for (int i = 0; i < 3; ++i) {
      V.row(3 * t + i) << pos(rng), pos(rng), z + (t % 3 == 0 ? depth(rng) : 0.0);
      inv_w[3 * t + i] = 1.0 / V(3 * t + i, 2);
    }
    F.row(t) << 3 * t, 3 * t + 1, 3 * t + 2;
  }
  F.row(7) << -1, 0, 1;  // skipped by both
  RasterOptions options;
  options.width = 223;
  options.height = 171;
  for (const Eigen::VectorXd& w : {Eigen::VectorXd(), inv_w}) {
    const RasterBuffer full = Rasterize(V, w, F, options);
    std::vector<int32_t> ids;
    for (int tile : {8, 32, 64}) {
      options.tile_size = tile;
      {
        ThreadLimit limit(tile == 8 ? 1 : 0);
        RasterizeTriangleIds(V, w, F, options, &ids);
      }
      EXPECT_EQ(ids, full.triangle) << "tile " << tile;
    }
    EXPECT_GT(full.NumCovered(), 10000);
  }
}

INSTANTIATE_TEST_SUITE_P(Seeds, RasterSeeded, ::testing::Values(1, 2, 3, 99));

TEST(Raster, CullsCounterClockwiseOnScreenAndRejectsBadInput) {
  const double x[3] = {0, 10, 0};
  const double y[3] = {0, 0, 10};  // clockwise on screen (y down)
  TriangleSetup setup;
  EXPECT_TRUE(SetupTriangle(x, y, CullMode::kCounterClockwise, &setup));
  const double y_flipped[3] = {0, 0, -10};
  EXPECT_FALSE(SetupTriangle(x, y_flipped, CullMode::kCounterClockwise, &setup));
  EXPECT_TRUE(SetupTriangle(x, y_flipped, CullMode::kNone, &setup));
  const double degenerate[3] = {0, 5, 10};
  EXPECT_FALSE(SetupTriangle(degenerate, degenerate, CullMode::kNone, &setup));
  const double nan_x[3] = {0, NAN, 0};
  EXPECT_FALSE(SetupTriangle(nan_x, y, CullMode::kNone, &setup));
  const double far_x[3] = {0, 1e9, 0};
  EXPECT_FALSE(SetupTriangle(far_x, y, CullMode::kNone, &setup));
  // Between pixel centres: no coverage.
  const double tiny_x[3] = {0.1, 0.4, 0.1};
  const double tiny_y[3] = {0.1, 0.1, 0.4};
  EXPECT_FALSE(SetupTriangle(tiny_x, tiny_y, CullMode::kNone, &setup));
}

}  // namespace
}  // namespace hmc
