#include "blending/ray_constraints.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <set>

#include "blending/robust_solver.h"
#include "blending/small_lgi_test_util.h"

namespace hmc {
namespace {

// A small actor (a denser marker lattice than the solvers' tests: a
// constrained marker has neighbours all round) and its lgi model.
struct RayFixture {
  explicit RayFixture(int seed) : seed(seed) {
    testing::LgiTestActorOptions o;
    o.seed = seed;
    o.grid = 32;
    o.markers_side = 6;
    o.jaw = false;
    actor = testing::MakeLgiTestActor(o);
    model = BuildLgiModel(actor, IndexOptions(), SmallLgiModel::SmallNn());
  }

  BundleFrame Bundles(int frame, const MatX3d& x) const {
    BundleFrame b;
    b.frame = frame;
    for (const Marker& m : actor.markers) {
      b.bundles[m.name] = EvaluateSurfacePoint(m.point, actor.neutral.F, x);
    }
    return b;
  }

  int seed;
  Actor actor;
  LgiModel model;
};

Vec3 SiteOn(const RayFixture& fx, int k, const MatX3d& x) {
  return EvaluateSurfacePoint(fx.actor.markers[k].point, fx.actor.neutral.F, x);
}

class RaySeeds : public ::testing::TestWithParam<int> {};

// Truth frames are combinations of the actor's shapes plus, at each marker
// dropped from its frame (as a marker hidden from one camera is dropped
// from bundles.csv), a smooth bump the dataset lacks (1.5 mm in a random
// direction, 8 mm wide), so the solve misses there. The dropped markers are
// given as rays from a camera in front of the face instead. After the
// constraint step every applied ray passes through its marker's surface
// point; with rays.depth "solve" the error left there is the solve's depth
// error along the ray (the move is perpendicular to it); with either depth
// the error there falls; the mesh moves only in the
// natural-neighbour region of the constrained markers, and the error over
// the rest of the face does not rise by more than 2 %.
TEST_P(RaySeeds, MarkersSeenByOneCameraLieOnTheirRays) {
  RayFixture fx(GetParam());
  const Actor& actor = fx.actor;
  const int K = static_cast<int>(actor.markers.size());
  std::mt19937 rng(500 + GetParam());
  std::uniform_int_distribution<int> pick_shape(0, static_cast<int>(actor.shapes.size()) - 1);
  std::uniform_int_distribution<int> pick_marker(0, K - 1);
  std::uniform_real_distribution<double> weight(0.6, 1.3);
  std::normal_distribution<double> normal(0.0, 1.0);
  const Vec3 camera(0, 10, 250);  // in front of the face, off its axis

  std::vector<MatX3d> truth;
  std::vector<BundleFrame> frames;
  std::vector<RayConstraint> rays;
  std::vector<std::set<int>> dropped;
  for (int f = 0; f < 12; ++f) {
    MatX3d x = actor.neutral.V;
    for (int s = 0; s < 2; ++s) x += weight(rng) * actor.shapes[pick_shape(rng)].displacement;
    std::set<int> drop;
    while (static_cast<int>(drop.size()) < 3) drop.insert(pick_marker(rng));
    for (int k : drop) {
      const Vec3 centre = SiteOn(fx, k, actor.neutral.V) + Vec3(2 * normal(rng), 2 * normal(rng), 0);
      const Vec3 bump = 1.5 * Vec3(normal(rng), normal(rng), normal(rng)).normalized();
      for (int v = 0; v < actor.NumVertices(); ++v) {
        const double r2 = (actor.neutral.V.row(v).transpose() - centre).squaredNorm();
        x.row(v) += std::exp(-r2 / (2 * 8.0 * 8.0)) * bump.transpose();
      }
    }
    truth.push_back(x);
    frames.push_back(fx.Bundles(f + 1, x));
    for (int k : drop) {
      frames.back().bundles.erase(actor.markers[k].name);
      const Vec3 p = SiteOn(fx, k, x);
      rays.push_back({f, k, "cam0", camera, (p - camera).normalized()});
    }
    dropped.push_back(drop);
  }

  const BlendshapeSolver global(actor.neutral, fx.model.data, [] {
    BlendshapeOptions o;
    o.bounded = true;
    return o;
  }());
  const LgiSolver lgi(actor.neutral, fx.model.data, fx.model.index, fx.model.nn, IndexOptions(),
                      SolveOptions());
  RobustSolver robust(actor.neutral, fx.model.data, lgi, fx.model.nn, global, SolveOptions(),
                      RobustOptions());
  const SolveResult solved = robust.SolveSequence(frames, {});
  std::vector<std::vector<char>> observed(frames.size(), std::vector<char>(K, 1));
  for (size_t f = 0; f < frames.size(); ++f) {
    for (int k : dropped[f]) observed[f][k] = 0;
  }
  for (const std::string depth : {"solve", "dataset"}) {
  std::vector<MatX3d> meshes = solved.meshes;
  RayConstraintOptions options;
  options.depth = depth;
  std::vector<MatX3d> displacements;
  for (const Shape& shape : actor.shapes) displacements.push_back(shape.displacement);
  const std::vector<RayResidual> residuals = ApplyRayConstraints(
      rays, fx.model.data.sites, actor.neutral.F, fx.model.nn, observed, {}, options, &meshes,
      SiteMotionCovariances(displacements, fx.model.data.sites, actor.neutral.F));

  // On the rays.
  ASSERT_EQ(residuals.size(), rays.size());
  for (const RayResidual& r : residuals) {
    ASSERT_EQ(r.status, RayStatus::kApplied);
    EXPECT_LT(r.after_mm, 1e-9);
  }
  // The error at the constrained markers.
  double before = 0, after = 0;
  for (const RayConstraint& ray : rays) {
    const Vec3 t = SiteOn(fx, ray.marker, truth[ray.frame_index]);
    const Vec3 e_before = SiteOn(fx, ray.marker, solved.meshes[ray.frame_index]) - t;
    const Vec3 e_after = SiteOn(fx, ray.marker, meshes[ray.frame_index]) - t;
    if (depth == "solve") {
      EXPECT_NEAR(e_after.norm(), std::abs(e_before.dot(ray.direction)), 1e-6);
    }
    before += e_before.norm();
    after += e_after.norm();
  }
  // Elsewhere: the vertices outside the constrained markers' own Voronoi
  // cells; and the mesh is unchanged outside their natural-neighbour
  // region.
  double rest_before = 0, rest_after = 0;
  for (size_t f = 0; f < truth.size(); ++f) {
    for (int v = 0; v < actor.NumVertices(); ++v) {
      double support = 0;
      for (int k : dropped[f]) support += fx.model.nn.weights.coeff(v, k);
      const double moved = (meshes[f].row(v) - solved.meshes[f].row(v)).norm();
      if (support == 0) {
        EXPECT_EQ(moved, 0.0);
      }
      if (dropped[f].count(fx.model.nn.cell(v))) continue;
      rest_before += (solved.meshes[f].row(v) - truth[f].row(v)).norm();
      rest_after += (meshes[f].row(v) - truth[f].row(v)).norm();
    }
  }
  std::printf("seed %d, depth %s: %zu rays, error at their markers %.4f -> %.4f mm (mean), "
              "the rest of the face %.5f -> %.5f mm (sum / 1e3)\n",
              GetParam(), depth.c_str(), rays.size(), before / rays.size(), after / rays.size(),
              rest_before / 1e3, rest_after / 1e3);
  EXPECT_LT(after, 0.75 * before);
  EXPECT_LT(rest_after, 1.02 * rest_before);
  }
}

// What is not applied, and why: a marker that is also a bundle, a ray
// farther than max_mm, a point behind the camera, a bad frame. Those leave
// the mesh as it is.
TEST(RayConstraints, RaysNotAppliedLeaveTheMeshAlone) {
  RayFixture fx(4);
  const Actor& actor = fx.actor;
  const MatX3d x = actor.neutral.V;
  const Vec3 p = SiteOn(fx, 5, x);
  const Vec3 camera(0, 0, 250);
  const Vec3 d = (p - camera).normalized();
  const Vec3 side = d.cross(Vec3::UnitX()).normalized();
  std::vector<MatX3d> meshes(2, x);
  std::vector<std::vector<char>> observed(2, std::vector<char>(actor.markers.size(), 0));
  observed[0][6] = 1;
  const std::vector<RayConstraint> rays = {
      {0, 6, "cam0", camera, (SiteOn(fx, 6, x) + Vec3(1, 0, 0) - camera).normalized()},
      {0, 5, "cam0", camera + 10 * side, d},             // 10 mm away
      {0, 7, "cam0", SiteOn(fx, 7, x) + Vec3(0, 0, -10), Vec3(0, 0, -1)},  // behind
      {1, 5, "cam0", camera + 0.5 * side, d}};
  RayConstraintOptions options;
  const std::vector<RayResidual> r =
      ApplyRayConstraints(rays, fx.model.data.sites, actor.neutral.F, fx.model.nn, observed,
                          {1, 0}, options, &meshes);
  EXPECT_EQ(r[0].status, RayStatus::kObserved);
  EXPECT_EQ(r[1].status, RayStatus::kTooFar);
  EXPECT_NEAR(r[1].before_mm, 10.0, 1e-9);
  EXPECT_EQ(r[2].status, RayStatus::kBehind);
  EXPECT_EQ(r[3].status, RayStatus::kBadFrame);
  EXPECT_EQ(meshes[0], x);
  EXPECT_EQ(meshes[1], x);
  const RayConstraintSummary s = SummarizeRays(r);
  EXPECT_EQ(s.applied, 0);
  EXPECT_EQ(s.observed + s.too_far + s.behind + s.bad_frame, 4);
}

INSTANTIATE_TEST_SUITE_P(Seeds, RaySeeds, ::testing::Values(1, 2, 3));

}  // namespace
}  // namespace hmc
