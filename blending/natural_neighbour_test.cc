#include "blending/natural_neighbour.h"

#include <cmath>
#include <cstdio>
#include <random>
#include <sstream>

#include <gtest/gtest.h>

#include "blending/test_meshes.h"
#include "blending/voronoi_uv.h"
#include "core/error.h"
#include "core/parallel.h"

namespace hmc {
namespace {

using testing_meshes::MakeGrid;
using testing_meshes::RandomSites;
using Weights = Eigen::SparseMatrix<double, Eigen::RowMajor>;

NaturalNeighbourOptions Options(const std::string& domain, int resolution = 256) {
  NaturalNeighbourOptions options;
  options.domain = domain;
  options.uv_resolution = resolution;
  return options;
}

Eigen::VectorXd Row(const Weights& w, int v) {
  Eigen::VectorXd row = Eigen::VectorXd::Zero(w.cols());
  for (Weights::InnerIterator it(w, v); it; ++it) row[it.col()] = it.value();
  return row;
}

void ExpectPartitionOfUnity(const NaturalNeighbourWeights& nn, int num_vertices,
                            int num_sites) {
  ASSERT_EQ(nn.weights.rows(), num_vertices);
  ASSERT_EQ(nn.weights.cols(), num_sites);
  ASSERT_EQ(nn.cell.size(), num_vertices);
  for (int v = 0; v < num_vertices; ++v) {
    double sum = 0.0;
    for (Weights::InnerIterator it(nn.weights, v); it; ++it) {
      ASSERT_TRUE(std::isfinite(it.value()));
      EXPECT_GE(it.value(), 0.0) << "vertex " << v;
      sum += it.value();
    }
    EXPECT_NEAR(sum, 1.0, 1e-12) << "vertex " << v;
  }
}

// Largest L1 change of the weight rows along one mesh edge, over the edges
// whose ends lie in different cells (`across`) and in the same cell.
struct Jumps {
  double across = 0.0;
  double inside = 0.0;
};
Jumps EdgeJumps(const TriMesh& mesh, const Weights& w, const Eigen::VectorXi& cell) {
  Jumps jumps;
  for (int f = 0; f < mesh.NumFaces(); ++f) {
    for (int i = 0; i < 3; ++i) {
      const int a = mesh.F(f, i), b = mesh.F(f, (i + 1) % 3);
      const double jump = (Row(w, a) - Row(w, b)).lpNorm<1>();
      double& slot = cell[a] != cell[b] ? jumps.across : jumps.inside;
      slot = std::max(slot, jump);
    }
  }
  return jumps;
}

// Sites at given UVs (found by barycentric location), so that the same
// diagram can be built on meshes of different resolution.
std::vector<SurfacePoint> SitesAtUV(const TriMesh& mesh, const MatX2d& uv) {
  std::vector<SurfacePoint> sites;
  for (int k = 0; k < uv.rows(); ++k) {
    const Vec2 p = uv.row(k).transpose();
    for (int f = 0; f < mesh.NumFaces(); ++f) {
      const Vec2 a = mesh.UV.row(mesh.FUV(f, 0)).transpose();
      const Vec2 b = mesh.UV.row(mesh.FUV(f, 1)).transpose();
      const Vec2 c = mesh.UV.row(mesh.FUV(f, 2)).transpose();
      Eigen::Matrix2d m;
      m << b - a, c - a;
      const Vec2 x = m.inverse() * (p - a);
      if (x.minCoeff() >= 0 && x.sum() <= 1) {
        SurfacePoint s;
        s.face = f;
        s.bary = Vec3(1 - x.sum(), x[0], x[1]);
        sites.push_back(s);
        break;
      }
    }
  }
  EXPECT_EQ(sites.size(), static_cast<size_t>(uv.rows()));
  return sites;
}

// `count` random UVs in [lo, hi]^2 at least `separation` apart.
MatX2d SeparatedUVs(int count, unsigned seed, double lo, double hi,
                    double separation) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> coordinate(lo, hi);
  MatX2d uv(0, 2);
  while (uv.rows() < count) {
    const Vec2 p(coordinate(rng), coordinate(rng));
    bool ok = true;
    for (int k = 0; k < uv.rows(); ++k) {
      ok = ok && (uv.row(k).transpose() - p).norm() >= separation;
    }
    if (!ok) continue;
    uv.conservativeResize(uv.rows() + 1, 2);
    uv.row(uv.rows() - 1) = p.transpose();
  }
  return uv;
}

class NaturalNeighbourTest : public testing::TestWithParam<std::string> {};

TEST_P(NaturalNeighbourTest, PartitionOfUnityNonNegativeOneAtSites) {
  for (unsigned seed : {1u, 2u, 3u}) {
    const TriMesh mesh = MakeGrid(31, 60.0, /*hole=*/seed == 2, /*bump=*/10.0);
    // Half the sites on vertices (where the weight must be exactly 1), half
    // inside triangles.
    std::vector<SurfacePoint> sites = RandomSites(mesh, 6, seed, 0.1, 0.9);
    std::vector<int> site_vertex;
    for (const SurfacePoint& s : RandomSites(mesh, 6, seed + 100, 0.1, 0.9)) {
      const int v = mesh.F(s.face, 0);
      site_vertex.push_back(v);
      sites.push_back(SurfacePointAtVertex(mesh.F, v));
    }
    const NaturalNeighbourWeights nn =
        ComputeNaturalNeighbourWeights(mesh, sites, Options(GetParam()));
    SCOPED_TRACE(testing::Message() << "seed " << seed);
    ExpectPartitionOfUnity(nn, mesh.NumVertices(), static_cast<int>(sites.size()));
    for (size_t j = 0; j < site_vertex.size(); ++j) {
      const int k = static_cast<int>(6 + j);
      EXPECT_EQ(nn.weights.coeff(site_vertex[j], k), 1.0) << "site " << k;
      EXPECT_EQ(nn.cell[site_vertex[j]], k);
    }
    // Natural neighbours: symmetric, never the site itself.
    for (int k = 0; k < static_cast<int>(sites.size()); ++k) {
      EXPECT_FALSE(nn.site_neighbours[k].empty());
      for (int j : nn.site_neighbours[k]) {
        EXPECT_NE(j, k);
        const auto& back = nn.site_neighbours[j];
        EXPECT_TRUE(std::find(back.begin(), back.end(), k) != back.end());
      }
    }
  }
}

// Continuity: the weights of two vertices joined by an edge differ by
// O(edge length), across cell borders as inside cells; so the largest jump
// across borders shrinks when the mesh is refined. A discontinuous blend
// (each vertex fully in its own cell) keeps a jump of 2 at any resolution.
TEST_P(NaturalNeighbourTest, ContinuousAcrossVoronoiEdges) {
  for (unsigned seed : {4u, 5u}) {
    const MatX2d uv = SeparatedUVs(8, seed, 0.1, 0.9, 0.15);
    double previous_across = 1e300;
    for (int n : {17, 33, 65}) {
      const TriMesh mesh = MakeGrid(n, 60.0, /*hole=*/false, /*bump=*/5.0);
      const NaturalNeighbourWeights nn = ComputeNaturalNeighbourWeights(
          mesh, SitesAtUV(mesh, uv), Options(GetParam(), 256));
      const Jumps jumps = EdgeJumps(mesh, nn.weights, nn.cell);
      SCOPED_TRACE(testing::Message() << "seed " << seed << " n " << n << " across "
                                      << jumps.across << " inside " << jumps.inside);
      std::printf("%s seed %u n %d: max L1 jump across borders %.4f, inside %.4f\n",
                  GetParam().c_str(), seed, n, jumps.across, jumps.inside);
      EXPECT_LT(jumps.across, 0.75 * previous_across);
      // On the same order as the change inside a cell.
      EXPECT_LE(jumps.across, 2.0 * jumps.inside);
      previous_across = jumps.across;
      if (n == 65) {
        Weights one_hot(mesh.NumVertices(), uv.rows());
        for (int v = 0; v < mesh.NumVertices(); ++v) one_hot.insert(v, nn.cell[v]) = 1.0;
        EXPECT_EQ(EdgeJumps(mesh, one_hot, nn.cell).across, 2.0);
        EXPECT_LT(jumps.across, 0.5);
      }
    }
  }
}

TEST_P(NaturalNeighbourTest, ExtrapolatesContinuouslyOutsideTheHull) {
  const TriMesh mesh = MakeGrid(41, 60.0, /*hole=*/true, /*bump=*/8.0);
  // Sites only in the middle: the border of the grid is outside their hull.
  const std::vector<SurfacePoint> sites = RandomSites(mesh, 8, 6, 0.35, 0.65);
  const NaturalNeighbourWeights nn =
      ComputeNaturalNeighbourWeights(mesh, sites, Options(GetParam(), 512));
  ExpectPartitionOfUnity(nn, mesh.NumVertices(), static_cast<int>(sites.size()));
  const Jumps jumps = EdgeJumps(mesh, nn.weights, nn.cell);
  EXPECT_LE(jumps.across, 1.5 * jumps.inside);
  // Outside the hull, more than one bundle still contributes (no hard
  // nearest-bundle fallback) on most border vertices.
  int blended = 0, border = 0;
  for (int v = 0; v < mesh.NumVertices(); ++v) {
    if (mesh.UV.row(v).minCoeff() > 0.05 && mesh.UV.row(v).maxCoeff() < 0.95) continue;
    ++border;
    if (nn.weights.row(v).nonZeros() > 1) ++blended;
  }
  EXPECT_GT(blended, border / 2);
}

TEST_P(NaturalNeighbourTest, DeterministicForAnyThreadCount) {
  const TriMesh mesh = MakeGrid(31, 60.0, true, 5.0);
  const std::vector<SurfacePoint> sites = RandomSites(mesh, 9, 11, 0.1, 0.9);
  NaturalNeighbourWeights reference;
  for (int threads : {1, 2, 3}) {
    ThreadLimit limit(threads);
    const NaturalNeighbourWeights nn =
        ComputeNaturalNeighbourWeights(mesh, sites, Options(GetParam()));
    if (threads == 1) {
      reference = nn;
      continue;
    }
    ASSERT_EQ(nn.weights.nonZeros(), reference.weights.nonZeros());
    EXPECT_EQ(Weights(nn.weights - reference.weights).norm(), 0.0);
    EXPECT_TRUE(nn.cell == reference.cell);
    EXPECT_EQ(nn.site_neighbours, reference.site_neighbours);
  }
}

TEST_P(NaturalNeighbourTest, WriteReadRoundTripIsExact) {
  const TriMesh mesh = MakeGrid(21, 60.0, true, 5.0);
  const std::vector<SurfacePoint> sites = RandomSites(mesh, 7, 12, 0.1, 0.9);
  const NaturalNeighbourWeights nn =
      ComputeNaturalNeighbourWeights(mesh, sites, Options(GetParam(), 128));
  std::stringstream stream;
  nn.Write(stream);
  const std::string bytes = stream.str();
  std::istringstream in(bytes);
  const NaturalNeighbourWeights back = NaturalNeighbourWeights::Read(in);
  ASSERT_EQ(back.weights.rows(), nn.weights.rows());
  ASSERT_EQ(back.weights.cols(), nn.weights.cols());
  ASSERT_EQ(back.weights.nonZeros(), nn.weights.nonZeros());
  for (int v = 0; v < mesh.NumVertices(); ++v) {
    EXPECT_TRUE(Row(back.weights, v) == Row(nn.weights, v));
  }
  EXPECT_TRUE(back.cell == nn.cell);
  EXPECT_EQ(back.site_neighbours, nn.site_neighbours);
  // Truncated or foreign data is an input error, never a crash.
  std::istringstream truncated(bytes.substr(0, bytes.size() / 2));
  EXPECT_THROW(NaturalNeighbourWeights::Read(truncated), InputError);
  std::istringstream foreign("not the weights at all, not at all");
  EXPECT_THROW(NaturalNeighbourWeights::Read(foreign), InputError);
}

INSTANTIATE_TEST_SUITE_P(Domains, NaturalNeighbourTest,
                         testing::Values("uv", "geodesic"));

// Sibson coordinates reproduce linear functions inside the sites' hull:
// sum_k lambda_k(v) s_k = v (linear precision). A partition of unity that is
// not Sibson's (nearest site, inverse distance) fails this.
TEST(NaturalNeighbourUvTest, LinearPrecisionInsideTheHull) {
  for (unsigned seed : {21u, 22u}) {
    const TriMesh mesh = MakeGrid(41, 60.0);
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> jitter(-0.03, 0.03);
    std::vector<SurfacePoint> sites;
    MatX2d site_uv(0, 2);
    for (int i = 0; i < 5; ++i) {
      for (int j = 0; j < 5; ++j) {
        const double u = 0.2 + 0.15 * i + jitter(rng), v = 0.2 + 0.15 * j + jitter(rng);
        const int x = static_cast<int>(std::lround(u * 40)), y = static_cast<int>(std::lround(v * 40));
        sites.push_back(SurfacePointAtVertex(mesh.F, y * 41 + x));
      }
    }
    const MatX2d uv_sites = SiteUVs(mesh, sites);
    const int resolution = 384;
    const NaturalNeighbourWeights nn =
        ComputeNaturalNeighbourWeights(mesh, sites, Options("uv", resolution));
    double worst = 0.0;
    for (int v = 0; v < mesh.NumVertices(); ++v) {
      const Vec2 uv = mesh.UV.row(v).transpose();
      if (uv.minCoeff() < 0.38 || uv.maxCoeff() > 0.62) continue;
      Vec2 blended = Vec2::Zero();
      for (Weights::InnerIterator it(nn.weights, v); it; ++it) {
        blended += it.value() * uv_sites.row(it.col()).transpose();
      }
      worst = std::max(worst, (blended - uv).norm());
    }
    // Discrete Sibson: exact up to the raster (a few pixels).
    EXPECT_LT(worst, 3.0 / resolution) << "seed " << seed;
  }
}

TEST(NaturalNeighbourOptionsTest, CheckRejectsBadValues) {
  NaturalNeighbourOptions options;
  EXPECT_TRUE(options.Check());
  options.domain = "euclidean";
  EXPECT_FALSE(options.Check());
  options.domain = "geodesic";
  options.uv_resolution = 4;
  EXPECT_FALSE(options.Check());
  TriMesh no_uv = MakeGrid(5, 10.0);
  no_uv.UV.resize(0, 2);
  no_uv.FUV.resize(0, 3);
  EXPECT_THROW(ComputeNaturalNeighbourWeights(no_uv, RandomSites(no_uv, 2, 1),
                                              NaturalNeighbourOptions()),
               InputError);
}

}  // namespace
}  // namespace hmc
