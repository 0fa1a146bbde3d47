#include "indexing/simplex.h"

#include <random>

#include <gtest/gtest.h>

namespace hmc {
namespace {

Vec3 RandomPoint(std::mt19937* rng, double scale) {
  std::uniform_real_distribution<double> u(-scale, scale);
  return Vec3(u(*rng), u(*rng), u(*rng));
}

TEST(Simplex, BarycentricReproducesPoint) {
  for (int seed = 1; seed <= 5; ++seed) {
    std::mt19937 rng(seed);
    const Vec3 a = RandomPoint(&rng, 10), b = RandomPoint(&rng, 10),
               c = RandomPoint(&rng, 10), d = RandomPoint(&rng, 10);
    for (int i = 0; i < 50; ++i) {
      const Vec3 p = RandomPoint(&rng, 15);
      std::array<double, 4> w;
      ASSERT_TRUE(TetBarycentric(a, b, c, d, p, &w));
      const Vec3 q = w[0] * a + w[1] * b + w[2] * c + w[3] * d;
      EXPECT_LT((q - p).norm(), 1e-9);
      EXPECT_NEAR(w[0] + w[1] + w[2] + w[3], 1.0, 1e-12);
    }
  }
}

// The closest point beats every point of a dense sampling of the simplex.
TEST(Simplex, ClosestPointBeatsSampling) {
  for (int seed = 1; seed <= 4; ++seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0, 1);
    for (int size = 1; size <= 4; ++size) {
      SimplexCorners s;
      s.size = size;
      for (int i = 0; i < 4; ++i) s.x[i] = RandomPoint(&rng, 10);
      for (int q = 0; q < 20; ++q) {
        const Vec3 p = RandomPoint(&rng, 20);
        const ClosestPoint cp = ClosestPointOnSimplex(s, p, 1e-12);
        Vec3 from_weights = Vec3::Zero();
        double sum = 0;
        for (int i = 0; i < size; ++i) {
          EXPECT_GE(cp.weights[i], -1e-12);
          from_weights += cp.weights[i] * s.x[i];
          sum += cp.weights[i];
        }
        EXPECT_NEAR(sum, 1.0, 1e-12);
        EXPECT_LT((from_weights - cp.point).norm(), 1e-9);
        EXPECT_NEAR((cp.point - p).norm(), cp.distance, 1e-9);
        for (int t = 0; t < 400; ++t) {
          double w[4] = {0, 0, 0, 0}, total = 0;
          for (int i = 0; i < size; ++i) total += (w[i] = -std::log(u(rng) + 1e-300));
          Vec3 x = Vec3::Zero();
          for (int i = 0; i < size; ++i) x += w[i] / total * s.x[i];
          EXPECT_LE(cp.distance, (x - p).norm() + 1e-9);
        }
      }
    }
  }
}

TEST(Simplex, QualityOfRegularAndFlat) {
  const Vec3 a(1, 1, 1), b(1, -1, -1), c(-1, 1, -1), d(-1, -1, 1);
  EXPECT_NEAR(TetQuality(a, b, c, d), 1.0, 1e-12);
  EXPECT_NEAR(TetQuality(a, b, c, 0.5 * (a + b)), 0.0, 1e-12);
  EXPECT_NEAR(TriangleQuality(Vec3(0, 0, 0), Vec3(1, 0, 0),
                              Vec3(0.5, std::sqrt(3.0) / 2, 0)),
              1.0, 1e-12);
  EXPECT_EQ(TriangleQuality(Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(2, 0, 0)), 0.0);
}

}  // namespace
}  // namespace hmc
