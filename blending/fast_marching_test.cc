#include "blending/fast_marching.h"

#include <cmath>
#include <cstdio>
#include <random>

#include <gtest/gtest.h>

#include "blending/test_meshes.h"

namespace hmc {
namespace {

using testing_meshes::MakeGrid;
using testing_meshes::MakeIcosphere;

struct Errors {
  double max = 0.0;
  double mean = 0.0;
  int wrong_label = 0;  // labels differing where the exact gap exceeds max error
};

// Sources at `count` random points given as fractions of the domain, snapped
// to the nearest vertex; exact distance from `exact(v, source_vertex)`.
template <typename Exact>
Errors MarchErrors(const TriMesh& mesh, int count, unsigned seed,
                   const Exact& exact, bool never_below = true) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> vertex(0, mesh.NumVertices() - 1);
  std::vector<MarchSource> sources;
  for (int k = 0; k < count; ++k) sources.push_back({vertex(rng), 0.0, k});
  const FastMarching marching(mesh.V, mesh.F);
  const FastMarching::Result result = marching.Run(sources);
  Errors errors;
  std::vector<double> best(mesh.NumVertices()), second(mesh.NumVertices());
  std::vector<int> best_k(mesh.NumVertices());
  for (int v = 0; v < mesh.NumVertices(); ++v) {
    best[v] = second[v] = 1e300;
    for (int k = 0; k < count; ++k) {
      const double d = exact(v, sources[k].vertex);
      if (d < best[v]) {
        second[v] = best[v];
        best[v] = d;
        best_k[v] = k;
      } else if (d < second[v]) {
        second[v] = d;
      }
    }
    const double error = result.distance[v] - best[v];
    if (never_below) {
      EXPECT_GE(error, -1e-9) << "fast marching underestimates at vertex " << v;
    }
    errors.max = std::max(errors.max, std::abs(error));
    errors.mean += std::abs(error) / mesh.NumVertices();
  }
  for (int v = 0; v < mesh.NumVertices(); ++v) {
    if (second[v] - best[v] > 2 * errors.max && result.label[v] != best_k[v]) {
      ++errors.wrong_label;
    }
  }
  return errors;
}

TEST(FastMarchingTest, PlaneMatchesEuclideanAndConvergesWithResolution) {
  const double size = 100.0;  // mm
  for (unsigned seed : {1u, 2u, 3u}) {
    double previous_max = 1e300, previous_mean = 1e300;
    for (int n : {17, 33, 65}) {
      const TriMesh mesh = MakeGrid(n, size);
      const double h = size / (n - 1);
      const Errors errors = MarchErrors(mesh, 3, seed, [&](int a, int b) {
        return (mesh.V.row(a) - mesh.V.row(b)).norm();
      });
      SCOPED_TRACE(testing::Message() << "seed " << seed << " n " << n);
      std::printf("plane seed %u n %d h %.3f mm: max error %.4f mm, mean %.4f mm\n",
                  seed, n, h, errors.max, errors.mean);
      // First-order scheme: the error is a small multiple of the edge length
      // (largest near the point sources, where the wavefront is not planar).
      EXPECT_LT(errors.max, 1.5 * h);
      EXPECT_LT(errors.max, previous_max);
      EXPECT_LT(errors.mean, previous_mean);
      EXPECT_EQ(errors.wrong_label, 0);
      previous_max = errors.max;
      previous_mean = errors.mean;
    }
  }
}

TEST(FastMarchingTest, SphereMatchesGreatCircleAndConvergesWithResolution) {
  const double radius = 50.0;  // mm
  for (unsigned seed : {4u, 5u}) {
    double previous_max = 1e300, previous_mean = 1e300;
    for (int levels : {2, 3, 4}) {
      const TriMesh mesh = MakeIcosphere(levels, radius);
      double h = 0;
      for (int i = 0; i < 3; ++i) {
        h = std::max(h, (mesh.V.row(mesh.F(0, i)) - mesh.V.row(mesh.F(0, (i + 1) % 3))).norm());
      }
      const Errors errors = MarchErrors(mesh, 2, seed, [&](int a, int b) {
        const double c = mesh.V.row(a).dot(mesh.V.row(b)) / (radius * radius);
        return radius * std::acos(std::clamp(c, -1.0, 1.0));
      }, /*never_below=*/false);  // the inscribed mesh is shorter than the sphere
      SCOPED_TRACE(testing::Message() << "seed " << seed << " levels " << levels);
      std::printf("sphere seed %u levels %d h %.3f mm: max error %.4f mm, mean %.4f mm\n",
                  seed, levels, h, errors.max, errors.mean);
      EXPECT_LT(errors.max, 2.0 * h);
      EXPECT_LT(errors.max, previous_max);
      EXPECT_LT(errors.mean, previous_mean);
      EXPECT_EQ(errors.wrong_label, 0);
      previous_max = errors.max;
      previous_mean = errors.mean;
    }
  }
}

TEST(FastMarchingTest, ObtuseTrianglesStayBoundedAndNeverUnderestimate) {
  // Jittered grid: many obtuse triangles, where the edge fallback applies.
  TriMesh mesh = MakeGrid(33, 100.0);
  const double h = 100.0 / 32;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> jitter(-0.35 * h, 0.35 * h);
  for (int v = 0; v < mesh.NumVertices(); ++v) {
    mesh.V(v, 0) += jitter(rng);
    mesh.V(v, 1) += jitter(rng);
  }
  const Errors errors = MarchErrors(mesh, 2, 8, [&](int a, int b) {
    return (mesh.V.row(a) - mesh.V.row(b)).norm();
  });
  EXPECT_LT(errors.max, 3.0 * h);
}

TEST(FastMarchingTest, BoundedMarchStopsAtTheBound) {
  const TriMesh mesh = MakeGrid(25, 100.0);
  const FastMarching marching(mesh.V, mesh.F);
  const FastMarching::Result sites = marching.Run({{0, 0.0, 0}, {624, 0.0, 1}});
  const int source = 12 * 25 + 12;  // the centre
  const FastMarching::Result full = marching.Run({{source, 0.0, 0}});
  FastMarching::Scratch scratch;
  for (int repeat = 0; repeat < 2; ++repeat) {  // scratch reuse
    marching.MarchBounded(source, sites.distance, &scratch);
    ASSERT_FALSE(scratch.accepted.empty());
    std::vector<char> accepted(mesh.NumVertices(), 0);
    for (int u : scratch.accepted) {
      accepted[u] = 1;
      const double d = FastMarching::DistanceOf(scratch, u);
      EXPECT_LT(d, sites.distance[u]);
      EXPECT_GE(d, full.distance[u] - 1e-9);
    }
    // Every vertex clearly inside the new cell is reached.
    for (int u = 0; u < mesh.NumVertices(); ++u) {
      if (full.distance[u] < sites.distance[u] - 5.0) {
        EXPECT_TRUE(accepted[u]) << u;
      }
    }
  }
}

}  // namespace
}  // namespace hmc
