#include "indexing/shape_index.h"

#include <sstream>

#include <gtest/gtest.h>

#include "core/error.h"
#include "core/jaw.h"

#include "indexing/lgi_test_actor.h"

namespace hmc {
namespace {

// Regions for tests: vertices within 25 mm of the bundle on the neutral.
std::vector<std::vector<int>> NearbyRegions(const Actor& actor,
                                            const ShapeData& data) {
  std::vector<std::vector<int>> regions(data.num_bundles);
  for (int k = 0; k < data.num_bundles; ++k) {
    for (int v = 0; v < actor.NumVertices(); ++v) {
      if ((actor.neutral.V.row(v) - data.site_neutral.row(k)).norm() < 25) {
        regions[k].push_back(v);
      }
    }
  }
  return regions;
}

// A bundle from a dataset shape lands exactly on its cloud point.
TEST(ShapeIndex, DatasetBundlesLandOnCloudPoints) {
  for (int seed = 1; seed <= 3; ++seed) {
    testing::LgiTestActorOptions o;
    o.seed = seed;
    const Actor actor = testing::MakeLgiTestActor(o);
    const ShapeData data = ComputeShapeData(actor);
    IndexOptions options;
    const ShapeIndex index =
        BuildShapeIndex(actor, data, NearbyRegions(actor, data), options);
    for (int n = 0; n < data.num_shapes; ++n) {
      const MatX3d x = actor.ShapePositions(n);
      for (int k = 0; k < data.num_bundles; ++k) {
        const Vec3 p = EvaluateSurfacePoint(data.sites[k], actor.neutral.F, x);
        const Vec3 u = UnskinBundle(data, k, actor.shapes[n].jaw, p);
        const IndexQuery q = index.bundles[k].Query(u, 0.0, options);
        EXPECT_TRUE(q.inside);
        const auto& shapes = index.bundles[k].point_shapes();
        const bool kept = std::count(shapes.begin(), shapes.end(), n) > 0;
        if (kept) {
          const int i = static_cast<int>(
              std::find(shapes.begin(), shapes.end(), n) - shapes.begin());
          EXPECT_EQ((index.bundles[k].points().row(i).transpose() - u).norm(),
                    0.0);
        }
      }
    }
  }
}

// The per-vertex shape lists hold exactly the shapes that move the vertex
// (what the blends visit instead of every shape), with their unskinned
// displacements b*_n(v) = T(theta_n)^-1 (x0 + b_n) - x0, recomputed here
// from the actor.
TEST(ShapeData, VertexShapesAreTheShapesThatMoveTheVertex) {
  for (int seed = 1; seed <= 3; ++seed) {
    testing::LgiTestActorOptions o;
    o.seed = seed;
    o.jaw = seed != 2;
    Actor actor = testing::MakeLgiTestActor(o);
    // Make shape 0 local: it leaves the left half of the face alone.
    for (int v = 0; v < actor.NumVertices(); ++v) {
      if (actor.neutral.V(v, 0) < 0) actor.shapes[0].displacement.row(v).setZero();
    }
    const ShapeData data = ComputeShapeData(actor);
    ASSERT_EQ(static_cast<int>(data.vertex_shape_start.size()),
              data.num_vertices + 1);
    std::vector<MatX3d> unskinned;
    for (const Shape& shape : actor.shapes) {
      const MatX3d x = actor.neutral.V + shape.displacement;
      unskinned.push_back(
          (actor.jaw_rig ? Unskin(*actor.jaw_rig, shape.jaw, x) : x) -
          actor.neutral.V);
    }
    int64_t without_shape0 = 0;
    for (int v = 0; v < data.num_vertices; ++v) {
      std::vector<int> moving;
      for (int n = 0; n < data.num_shapes; ++n) {
        const Eigen::Vector3f b = unskinned[n].row(v).transpose().cast<float>();
        const float* listed_b = data.Displacement(v, n);
        if (!b.isZero(0)) {
          moving.push_back(n);
          ASSERT_NE(listed_b, nullptr) << "vertex " << v << " shape " << n;
          EXPECT_EQ(Eigen::Vector3f(listed_b[0], listed_b[1], listed_b[2]), b);
        } else {
          EXPECT_EQ(listed_b, nullptr) << "vertex " << v << " shape " << n;
        }
      }
      const std::vector<int> listed(
          data.vertex_shapes.begin() + data.vertex_shape_start[v],
          data.vertex_shapes.begin() + data.vertex_shape_start[v + 1]);
      EXPECT_EQ(listed, moving) << "vertex " << v;
      without_shape0 += moving.empty() || moving[0] != 0;
    }
    // Unskinning with the jaw must not leave rounding noise behind.
    EXPECT_GE(without_shape0, data.num_vertices / 3) << "seed " << seed;
  }
}

// A shape that does not move a bundle's region is pruned from its cloud;
// a copy of a shape is merged; a shape equal to another at the marker but
// different elsewhere in the region is kept.
TEST(ShapeIndex, PruningAndMergingLookAtTheWholeRegion) {
  testing::LgiTestActorOptions o;
  o.jaw = false;
  o.base_shapes = 2;
  Actor actor = testing::MakeLgiTestActor(o);
  const int V = actor.NumVertices();
  Shape still;
  still.name = "still";
  still.displacement = MatX3d::Zero(V, 3);
  actor.shapes.push_back(still);
  Shape copy = actor.shapes[0];
  copy.name = "copy";
  actor.shapes.push_back(copy);
  // Equal to shape 0 at bundle 0's surface point, different 10 mm away.
  ShapeData probe = ComputeShapeData(actor);
  Shape twist = actor.shapes[0];
  twist.name = "twist";
  const Vec3 site = probe.site_neutral.row(0).transpose();
  for (int v = 0; v < V; ++v) {
    const double r = (actor.neutral.V.row(v).transpose() - site).norm();
    if (r > 8 && r < 14) twist.displacement(v, 2) += 1.0;
  }
  actor.shapes.push_back(twist);
  const ShapeData data = ComputeShapeData(actor);
  IndexOptions options;
  const ShapeIndex index =
      BuildShapeIndex(actor, data, NearbyRegions(actor, data), options);
  const auto& shapes = index.bundles[0].point_shapes();
  auto has = [&](int n) {
    return std::count(shapes.begin(), shapes.end(), n) > 0;
  };
  const int n_still = actor.FindShape("still");
  const int n_copy = actor.FindShape("copy");
  const int n_twist = actor.FindShape("twist");
  EXPECT_FALSE(has(n_still));
  EXPECT_FALSE(has(n_copy));
  EXPECT_TRUE(has(n_twist));
  EXPECT_GE(index.clouds[0].pruned_motion, 1);
  EXPECT_GE(index.clouds[0].merged, 1);
}

TEST(ShapeIndex, WriteReadRoundTripAndVersionCheck) {
  const Actor actor = testing::MakeLgiTestActor({});
  const ShapeData data = ComputeShapeData(actor);
  IndexOptions options;
  ShapeIndex index =
      BuildShapeIndex(actor, data, NearbyRegions(actor, data), options);
  index.options_hash = 77;
  std::stringstream buffer;
  index.Write(buffer);
  const ShapeIndex back = ShapeIndex::Read(buffer);
  EXPECT_EQ(back.actor_hash, index.actor_hash);
  EXPECT_EQ(back.options_hash, 77u);
  ASSERT_EQ(back.bundles.size(), index.bundles.size());
  for (size_t k = 0; k < back.bundles.size(); ++k) {
    EXPECT_EQ(back.bundles[k].points(), index.bundles[k].points());
    EXPECT_EQ(back.clouds[k].merged, index.clouds[k].merged);
  }
  std::string bytes = buffer.str();
  bytes[8] = 99;  // format version
  std::stringstream bad(bytes);
  EXPECT_THROW(ShapeIndex::Read(bad), InputError);
}

}  // namespace
}  // namespace hmc
