#include "indexing/bundle_index.h"

#include <algorithm>
#include <random>
#include <set>
#include <sstream>

#include <gtest/gtest.h>

#include "core/error.h"

namespace hmc {
namespace {

// The index's mechanics (queries, containment, projection), independent of
// the default pruning, which is tuned for faces (edges <= 6 mm would leave
// these 5-10 mm test clouds without tetrahedra).
IndexOptions MechanicsOptions() {
  IndexOptions options;
  options.min_tet_quality = 1e-3;
  options.max_edge_mm = 0.0;
  return options;
}

BundleIndex RandomIndex(int seed, int points, const IndexOptions& options) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0.0, 5.0);
  MatX3d cloud(points, 3);
  std::vector<int> shapes(points);
  for (int i = 0; i < points; ++i) {
    cloud.row(i) << g(rng), g(rng), 0.5 * g(rng);
    shapes[i] = i - 1;
  }
  return BundleIndex::Build(cloud, shapes, options);
}

std::set<int> Ids(const IndexQuery& q) {
  std::set<int> ids;
  for (const auto& c : q.candidates) ids.insert(c.simplex);
  return ids;
}

// The grid query returns exactly what testing every simplex returns (the
// same simplices, closest points and weights), inside and outside, for clouds of several sizes and seeds and coarse/fine grids.
TEST(BundleIndex, GridQueryMatchesBruteForce) {
  for (int seed = 1; seed <= 4; ++seed) {
    // Small clouds of overlapping simplices (a projection's second ring of
    // cells lists more entries than there are simplices: one pass over all)
    // and a larger cloud of short-edged ones (the rings stay sparse).
    for (int cells : {1, 5, 16, 24}) {
      IndexOptions options = MechanicsOptions();
      options.grid_max_cells = cells;
      options.min_tet_quality = 0.05;
      if (cells == 24) options.max_edge_mm = 4.0;
      const BundleIndex index =
          RandomIndex(seed, cells == 24 ? 60 : 7 + 2 * seed, options);
      std::mt19937 rng(100 + seed);
      std::normal_distribution<double> g(0.0, cells == 24 ? 4.0 : 9.0);
      int inside = 0, outside = 0;
      for (int t = 0; t < 150; ++t) {
        const Vec3 p(g(rng), g(rng), g(rng));
        for (double slack : {0.0, 0.5}) {
          const IndexQuery fast = index.Query(p, slack, options);
          const IndexQuery slow = index.QueryBruteForce(p, slack, options);
          ASSERT_EQ(fast.inside, slow.inside);
          EXPECT_NEAR(fast.distance, slow.distance, 1e-12);
          ASSERT_EQ(Ids(fast), Ids(slow));
          // The same closest points and weights too (the grid query takes
          // the tetrahedra's from their faces, computed once per query).
          for (size_t i = 0; i < fast.candidates.size(); ++i) {
            const IndexCandidate& a = fast.candidates[i];
            const IndexCandidate& b = slow.candidates[i];
            EXPECT_NEAR((a.point - b.point).norm(), 0.0, 1e-12);
            for (int c = 0; c < 4; ++c) {
              EXPECT_NEAR(a.weights[c], b.weights[c], 1e-12);
            }
          }
          (fast.inside ? inside : outside)++;
          for (const auto& c : fast.candidates) {
            EXPECT_LE(c.distance, fast.distance + slack + options.on_data_mm);
          }
        }
      }
      EXPECT_GT(inside, 0);
      EXPECT_GT(outside, 0);
    }
  }
}

// Query skips the inside test for points beyond a plane that holds the
// cloud; points within on_data_mm of a cloud point (pushed out of the hull
// in every direction) must still be found inside, as by brute force.
TEST(BundleIndex, PointsJustOutsideTheHullAreStillOnTheData) {
  for (int seed = 1; seed <= 3; ++seed) {
    IndexOptions options = MechanicsOptions();
    const BundleIndex index = RandomIndex(seed, 9, options);
    std::mt19937 rng(200 + seed);
    std::normal_distribution<double> g(0.0, 1.0);
    int pushed_out = 0;
    for (int i = 0; i < index.NumPoints(); ++i) {
      for (int t = 0; t < 20; ++t) {
        const Vec3 dir = Vec3(g(rng), g(rng), g(rng)).normalized();
        for (double scale : {0.5, 2.0}) {
          const Vec3 p = index.points().row(i).transpose() +
                         scale * options.on_data_mm * dir;
          const IndexQuery fast = index.Query(p, 0.0, options);
          const IndexQuery slow = index.QueryBruteForce(p, 0.0, options);
          ASSERT_EQ(fast.inside, slow.inside);
          ASSERT_EQ(Ids(fast), Ids(slow));
          if (scale < 1) {
            EXPECT_TRUE(fast.inside);
          } else {
            pushed_out += !fast.inside;
          }
        }
      }
    }
    EXPECT_GT(pushed_out, 0);  // some directions leave the hull
  }
}

// At the corners, edge midpoints and face centroids of every kept
// tetrahedron, the query finds that point of the tetrahedron's face, with
// convex weights that reproduce it, once: no two candidates have the same
// corners of non-zero weight.
TEST(BundleIndex, RobustAtFacesEdgesAndCorners) {
  for (int seed = 1; seed <= 3; ++seed) {
    IndexOptions options = MechanicsOptions();
    const BundleIndex index = RandomIndex(seed, 8, options);
    int tested = 0;
    for (int s = 0; s < static_cast<int>(index.simplices().size()); ++s) {
      const SimplexCorners c = index.Corners(s);
      if (c.size != 4) continue;
      std::vector<Vec3> probes;
      for (int i = 0; i < 4; ++i) {
        probes.push_back(c.x[i]);
        for (int j = i + 1; j < 4; ++j) probes.push_back(0.5 * (c.x[i] + c.x[j]));
      }
      for (int skip = 0; skip < 4; ++skip) {
        Vec3 centroid = Vec3::Zero();
        for (int i = 0; i < 4; ++i) {
          if (i != skip) centroid += c.x[i] / 3.0;
        }
        probes.push_back(centroid);
      }
      for (const Vec3& p : probes) {
        const IndexQuery q = index.Query(p, 0.0, options);
        ASSERT_TRUE(q.inside);
        bool found = false;
        std::set<std::vector<int>> supports;
        for (const auto& cand : q.candidates) {
          const SimplexCorners cc = index.Corners(cand.simplex);
          Vec3 x = Vec3::Zero();
          double sum = 0;
          for (int i = 0; i < cc.size; ++i) {
            EXPECT_GE(cand.weights[i], 0.0);
            x += cand.weights[i] * cc.x[i];
            sum += cand.weights[i];
          }
          EXPECT_NEAR(sum, 1.0, 1e-12);
          EXPECT_LT((x - p).norm(), 1e-9);
          // One candidate per support: the one for p's face of s has all
          // its non-zero weights on corners of s.
          const CloudSimplex& cs = index.simplices()[cand.simplex];
          const CloudSimplex& ss = index.simplices()[s];
          bool on_s = true;
          for (int i = 0; i < cs.size; ++i) {
            if (cand.weights[i] == 0.0) continue;
            on_s &= std::count(ss.corner.begin(), ss.corner.begin() + ss.size,
                               cs.corner[i]) > 0;
          }
          found |= on_s;
          std::vector<int> support;
          for (int i = 0; i < cs.size; ++i) {
            if (cand.weights[i] > 0) support.push_back(cs.corner[i]);
          }
          std::sort(support.begin(), support.end());
          EXPECT_TRUE(supports.insert(support).second) << "duplicate support";
        }
        EXPECT_TRUE(found) << "simplex " << s;
        ++tested;
      }
    }
    EXPECT_GT(tested, 0);
  }
}

// A point outside the cloud lands on the closest point of the union of
// simplices, found by brute force over all of them.
TEST(BundleIndex, OutsideLandsOnClosestPoint) {
  for (int seed = 1; seed <= 4; ++seed) {
    IndexOptions options = MechanicsOptions();
    const BundleIndex index = RandomIndex(seed, 9, options);
    std::mt19937 rng(seed);
    std::normal_distribution<double> g(0.0, 1.0);
    for (int t = 0; t < 40; ++t) {
      const Vec3 dir = Vec3(g(rng), g(rng), g(rng)).normalized();
      const Vec3 p = dir * (30 + 20 * std::abs(g(rng)));
      const IndexQuery q = index.Query(p, 0.0, options);
      ASSERT_FALSE(q.inside);
      double best = 1e300;
      for (int s = 0; s < static_cast<int>(index.simplices().size()); ++s) {
        best = std::min(best, ClosestPointOnSimplex(index.Corners(s), p, 0).distance);
      }
      EXPECT_NEAR(q.distance, best, 1e-9);
      ASSERT_FALSE(q.candidates.empty());
      for (const auto& c : q.candidates) {
        EXPECT_NEAR((c.point - p).norm(), best, options.on_data_mm + 1e-9);
      }
    }
  }
}

TEST(BundleIndex, LowDimensionalClouds) {
  IndexOptions options = MechanicsOptions();
  // Two points: a segment; one point: itself.
  MatX3d two(2, 3);
  two << 0, 0, 0, 10, 0, 0;
  const BundleIndex seg = BundleIndex::Build(two, {-1, 0}, options);
  const IndexQuery q = seg.Query(Vec3(4, 0, 0), 0.0, options);
  ASSERT_TRUE(q.inside);
  ASSERT_EQ(q.candidates.size(), 1u);
  EXPECT_NEAR(q.candidates[0].weights[1], 0.4, 1e-12);
  const IndexQuery off = seg.Query(Vec3(4, 3, 0), 0.0, options);
  EXPECT_FALSE(off.inside);
  EXPECT_NEAR(off.distance, 3.0, 1e-12);
  MatX3d one(1, 3);
  one << 1, 2, 3;
  const BundleIndex dot = BundleIndex::Build(one, {-1}, options);
  const IndexQuery q1 = dot.Query(Vec3(1, 2, 4), 0.0, options);
  EXPECT_NEAR(q1.distance, 1.0, 1e-12);
  EXPECT_EQ(q1.candidates.size(), 1u);
}

TEST(BundleIndex, PruningRespectsQualityAndExtent) {
  IndexOptions options = MechanicsOptions();
  options.min_tet_quality = 0.2;
  options.max_edge_mm = 12.0;
  const BundleIndex index = RandomIndex(3, 10, options);
  for (int s = 0; s < static_cast<int>(index.simplices().size()); ++s) {
    const SimplexCorners c = index.Corners(s);
    for (int i = 0; i < c.size; ++i) {
      for (int j = i + 1; j < c.size; ++j) {
        EXPECT_LE((c.x[i] - c.x[j]).norm(), 12.0 + 1e-12);
      }
    }
    if (c.size == 4) {
      EXPECT_GE(TetQuality(c.x[0], c.x[1], c.x[2], c.x[3]), 0.2);
    }
  }
  EXPECT_EQ(index.stats().tets_candidate, 210);
  // The thresholds prune: the same cloud without them keeps more, and
  // every tetrahedron kept with them is one that passes both.
  IndexOptions loose = MechanicsOptions();
  loose.min_tet_quality = 0.0;
  loose.max_edge_mm = 1e9;
  const BundleIndex unpruned = RandomIndex(3, 10, loose);
  EXPECT_GT(index.stats().tets_kept, 0);
  EXPECT_LT(index.stats().tets_kept, unpruned.stats().tets_kept);
}

// The kept simplices are exactly those the index's definition gives when
// every 4-, 3- and 2-subset of the cloud is tested (docs/method.md,
// "Tetrahedralization"), in the same order: tetrahedra, then triangles that
// are not faces of kept tetrahedra, then edges that are not sides of either,
// then the points; within each, corners ascending, lexicographic. Under the
// edge bound alone and with the nearest-neighbour bound.
TEST(BundleIndex, SimplicesEqualTheBruteForceDefinition) {
  for (int seed : {1, 2, 3}) {
    for (int points : {9, 24, 40}) {
      for (int k_near : {0, 3, 8}) {
        IndexOptions options;
        options.min_tet_quality = 0.1;
        options.min_triangle_quality = 0.1;
        options.max_edge_mm = 9.0;
        options.max_edge_neighbours = k_near;
        const BundleIndex index = RandomIndex(seed, points, options);
        const MatX3d& x = index.points();
        const int P = index.NumPoints();
        auto d = [&](int i, int j) { return (x.row(i) - x.row(j)).norm(); };
        auto kth = [&](int i) {  // distance to i's k-th nearest other point
          std::vector<double> r;
          for (int j = 0; j < P; ++j) {
            if (j != i) r.push_back(d(i, j));
          }
          std::sort(r.begin(), r.end());
          return k_near > 0 && k_near <= static_cast<int>(r.size()) ? r[k_near - 1] : 1e300;
        };
        std::vector<double> near(P);
        for (int i = 0; i < P; ++i) near[i] = kth(i);
        auto edge_ok = [&](int i, int j) {
          return d(i, j) <= 9.0 && (d(i, j) <= near[i] || d(i, j) <= near[j]);
        };
        auto p = [&](int i) -> Vec3 { return x.row(i).transpose(); };
        std::vector<std::vector<int>> expected;
        std::set<std::vector<int>> faces, sides;
        for (int i = 0; i < P; ++i)
          for (int j = i + 1; j < P; ++j)
            for (int k = j + 1; k < P; ++k)
              for (int l = k + 1; l < P; ++l) {
                if (!(edge_ok(i, j) && edge_ok(i, k) && edge_ok(i, l) && edge_ok(j, k) &&
                      edge_ok(j, l) && edge_ok(k, l))) {
                  continue;
                }
                const double q = TetQuality(p(i), p(j), p(k), p(l));
                if (q < 0.1 || q == 0.0) continue;
                expected.push_back({i, j, k, l});
                faces.insert({{i, j, k}, {i, j, l}, {i, k, l}, {j, k, l}});
              }
        for (int i = 0; i < P; ++i)
          for (int j = i + 1; j < P; ++j)
            for (int k = j + 1; k < P; ++k) {
              if (!(edge_ok(i, j) && edge_ok(i, k) && edge_ok(j, k))) continue;
              const bool face = faces.count({i, j, k}) > 0;
              if (!face) {
                const double q = TriangleQuality(p(i), p(j), p(k));
                if (q < 0.1 || q == 0.0) continue;
                expected.push_back({i, j, k});
              }
              sides.insert({{i, j}, {i, k}, {j, k}});
            }
        for (int i = 0; i < P; ++i)
          for (int j = i + 1; j < P; ++j) {
            if (edge_ok(i, j) && !sides.count({i, j}) && d(i, j) > 0) expected.push_back({i, j});
          }
        for (int i = 0; i < P; ++i) expected.push_back({i});
        std::vector<std::vector<int>> kept;
        for (const CloudSimplex& s : index.simplices()) {
          kept.emplace_back(s.corner.begin(), s.corner.begin() + s.size);
        }
        EXPECT_EQ(kept, expected) << "seed " << seed << ", " << points << " points, k " << k_near;
        if (k_near == 0 && points == 40) {
          EXPECT_GT(index.stats().tets_kept, 0) << seed << " " << points;
        }
      }
    }
  }
}

// The nearest-neighbour bound keeps the tetrahedra of a dense cloud to a
// multiple of its points (the edge bound alone keeps ~5,000 per point on
// these clouds) and still covers the volume the unbounded ones cover: with
// k = 24 nearly every position inside one of those is inside one of these
// (the positions are drawn uniformly in randomly drawn unbounded ones).
bool InSomeTet(const BundleIndex& index, const Vec3& p, const IndexOptions& options) {
  for (const IndexCandidate& c : index.Query(p, 0.0, options).candidates) {
    if (index.simplices()[c.simplex].size == 4) return true;
  }
  return false;
}

TEST(BundleIndex, NeighbourBoundKeepsDenseCloudsSmallAndCovered) {
  constexpr int kPoints = 150;
  for (int seed : {4, 5}) {
    IndexOptions options;
    options.min_tet_quality = 0.1;
    options.max_edge_mm = 8.0;
    const BundleIndex all = RandomIndex(seed, kPoints, options);
    options.max_edge_neighbours = 24;
    const BundleIndex bounded = RandomIndex(seed, kPoints, options);
    EXPECT_LT(bounded.stats().tets_kept, 200 * kPoints);
    EXPECT_LT(bounded.stats().tets_kept * 20, all.stats().tets_kept);
    // Positions inside randomly drawn unbounded tetrahedra.
    std::mt19937 rng(seed + 100);
    std::uniform_int_distribution<int64_t> pick(0, all.stats().tets_kept - 1);
    std::exponential_distribution<double> e(1.0);
    const int in_all = 2000;
    int in_bounded = 0;
    for (int t = 0; t < in_all; ++t) {
      const SimplexCorners c = all.Corners(static_cast<int>(pick(rng)));
      double w[4], sum = 0;
      for (double& wi : w) sum += (wi = e(rng));  // uniform on the simplex
      Vec3 p = Vec3::Zero();
      for (int i = 0; i < 4; ++i) p += w[i] / sum * c.x[i];
      in_bounded += InSomeTet(bounded, p, options);
    }
    EXPECT_GE(in_bounded, 0.98 * in_all) << in_bounded << " of " << in_all;
  }
}

TEST(BundleIndex, WriteReadRoundTrip) {
  IndexOptions options = MechanicsOptions();
  const BundleIndex index = RandomIndex(5, 9, options);
  std::stringstream buffer;
  index.Write(buffer);
  const BundleIndex back = BundleIndex::Read(buffer);
  EXPECT_EQ(back.points(), index.points());
  EXPECT_EQ(back.point_shapes(), index.point_shapes());
  ASSERT_EQ(back.simplices().size(), index.simplices().size());
  std::mt19937 rng(1);
  std::normal_distribution<double> g(0.0, 8.0);
  for (int t = 0; t < 50; ++t) {
    const Vec3 p(g(rng), g(rng), g(rng));
    EXPECT_EQ(Ids(back.Query(p, 0.1, options)), Ids(index.Query(p, 0.1, options)));
  }
  std::stringstream truncated(buffer.str().substr(0, buffer.str().size() / 2));
  EXPECT_THROW(BundleIndex::Read(truncated), InputError);
}

}  // namespace
}  // namespace hmc
