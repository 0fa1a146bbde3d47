#include "blending/baseline_interp.h"

#include <gtest/gtest.h>

#include <random>

#include "core/jaw.h"
#include "synth/synth_actor.h"

namespace hmc {
namespace {

struct Fixture {
  explicit Fixture(int seed)
      : actor([&] {
          SynthActorOptions o;
          o.seed = seed;
          o.grid_u = 40;
          o.grid_v = 32;
          o.dataset_inbetweens = false;
          o.dataset_combos = false;
          return SynthesizeActor(o);
        }()),
        data(ComputeShapeData(actor)) {}
  Actor actor;
  ShapeData data;
};

class InterpSeeded : public ::testing::TestWithParam<int> {};

TEST_P(InterpSeeded, PassesThroughTheBundles) {
  const Fixture fx(GetParam());
  std::mt19937 rng(GetParam());
  std::normal_distribution<double> g(0, 2.0);
  BundleFrame frame;
  frame.frame = 5;
  std::vector<Vec3> offset(fx.data.num_bundles);
  for (int k = 0; k < fx.data.num_bundles; ++k) {
    offset[k] = Vec3(g(rng), g(rng), g(rng));
    // Markers closer than merge_mm share one constraint: move them
    // together so exact interpolation is possible.
    for (int j = 0; j < k; ++j) {
      if ((fx.data.site_neutral.row(j) - fx.data.site_neutral.row(k)).norm() <=
          InterpOptions().merge_mm) {
        offset[k] = offset[j];
        break;
      }
    }
    if (k % 5 == 2) continue;  // missing markers
    frame.bundles[fx.data.bundle_names[k]] =
        fx.data.site_neutral.row(k).transpose() + offset[k];
  }
  frame.bundles["not_a_marker"] = Vec3::Zero();
  const InterpSolver solver(fx.actor.neutral, fx.data, InterpOptions());
  MatX3d mesh;
  const FrameSolve fs = solver.SolveFrame(frame, JawPose(), &mesh);
  ASSERT_TRUE(fs.ok) << fs.reason;
  EXPECT_EQ(fs.unknown_markers, 1);
  for (int k = 0; k < fx.data.num_bundles; ++k) {
    const auto it = frame.bundles.find(fx.data.bundle_names[k]);
    if (it == frame.bundles.end()) {
      EXPECT_EQ(fs.bundles[k].status, BundleSolve::Status::kUnused);
      continue;
    }
    const Vec3 x =
        EvaluateSurfacePoint(fx.data.sites[k], fx.actor.neutral.F, mesh);
    EXPECT_LT((x - it->second).norm(), 1e-8) << "bundle " << k;
    EXPECT_LT(fs.bundles[k].residual, 1e-8);
  }
}

TEST_P(InterpSeeded, ReproducesATranslationAndAPureJawMotion) {
  const Fixture fx(GetParam());
  std::mt19937 rng(GetParam() + 50);
  std::uniform_real_distribution<double> u(-5, 5);
  const Vec3 t(u(rng), u(rng), u(rng));
  BundleFrame frame;
  for (int k = 0; k < fx.data.num_bundles; ++k) {
    frame.bundles[fx.data.bundle_names[k]] =
        fx.data.site_neutral.row(k).transpose() + t;
  }
  const InterpSolver solver(fx.actor.neutral, fx.data, InterpOptions());
  MatX3d mesh;
  ASSERT_TRUE(solver.SolveFrame(frame, JawPose(), &mesh).ok);
  MatX3d expected = fx.actor.neutral.V;
  expected.rowwise() += t.transpose();
  EXPECT_LT((mesh - expected).cwiseAbs().maxCoeff(), 1e-8);

  // Bundles that only follow the jaw unskin to the neutral: the result is
  // the jaw-skinned neutral.
  ASSERT_TRUE(fx.data.jaw_rig.has_value());
  JawPose jaw;
  jaw.open_deg = 6 + u(rng);
  jaw.protrude_mm = 0.2 * u(rng);
  for (int k = 0; k < fx.data.num_bundles; ++k) {
    frame.bundles[fx.data.bundle_names[k]] =
        SkinBundle(fx.data, k, jaw, fx.data.site_neutral.row(k).transpose());
  }
  ASSERT_TRUE(solver.SolveFrame(frame, jaw, &mesh).ok);
  const MatX3d skinned = Skin(*fx.data.jaw_rig, jaw, fx.actor.neutral.V);
  EXPECT_LT((mesh - skinned).cwiseAbs().maxCoeff(), 1e-8);
}

TEST_P(InterpSeeded, SequenceFlagsFramesWithTooFewBundles) {
  const Fixture fx(GetParam());
  std::vector<BundleFrame> frames(2);
  frames[0].frame = 1;
  frames[1].frame = 2;
  for (int k = 0; k < fx.data.num_bundles; ++k) {
    frames[0].bundles[fx.data.bundle_names[k]] =
        fx.data.site_neutral.row(k).transpose() + Vec3(0, 1, 0);
  }
  frames[1].bundles[fx.data.bundle_names[0]] = Vec3::Zero();
  const InterpSolver solver(fx.actor.neutral, fx.data, InterpOptions());
  const SolveResult r = solver.SolveSequence(frames, {});
  EXPECT_TRUE(r.frames[0].ok);
  EXPECT_FALSE(r.frames[1].ok);
  EXPECT_EQ((r.meshes[1] - r.meshes[0]).cwiseAbs().maxCoeff(), 0.0);
}

INSTANTIATE_TEST_SUITE_P(Seeds, InterpSeeded, ::testing::Values(1, 2, 5));

}  // namespace
}  // namespace hmc
