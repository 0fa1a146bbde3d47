#include "blending/lgi_rbf.h"

#include <gtest/gtest.h>

#include <random>

#include "blending/small_lgi_test_util.h"
#include "core/jaw.h"
#include "blending/thread_count_test_util.h"

namespace hmc {
namespace {

// A small actor with its real lgi model (index + natural-neighbour weights).
struct RbfFixture : SmallLgiModel {
  explicit RbfFixture(int seed, bool jaw, LgiRbfOptions rbf_options = {})
      : SmallLgiModel(seed, jaw),
        rbf(actor.neutral, model.data, lgi, rbf_options) {}

  LgiRbfSolver rbf;
};

// Random mixtures of two dataset shapes (not dataset shapes themselves), with
// the zero jaw pose so the output can pass exactly through the bundles.
std::vector<BundleFrame> MixtureFrames(const RbfFixture& fx, int count,
                                       std::mt19937* rng) {
  std::uniform_int_distribution<int> pick(
      0, static_cast<int>(fx.actor.shapes.size()) - 1);
  std::uniform_real_distribution<double> t(0.2, 0.8);
  std::vector<BundleFrame> frames;
  for (int f = 0; f < count; ++f) {
    const int a = pick(*rng), b = pick(*rng);
    const double s = t(*rng);
    const MatX3d x = fx.actor.neutral.V + s * fx.actor.shapes[a].displacement +
                     (1 - s) * fx.actor.shapes[b].displacement;
    frames.push_back(fx.Bundles(f + 1, x));
  }
  return frames;
}

class LgiRbfSeeds : public ::testing::TestWithParam<int> {};

TEST_P(LgiRbfSeeds, PassesThroughTheBundles) {
  const RbfFixture fx(GetParam(), /*jaw=*/false);
  std::mt19937 rng(100 + GetParam());
  const std::vector<BundleFrame> frames = MixtureFrames(fx, 6, &rng);
  const SolveResult result = fx.rbf.SolveSequence(frames, {});
  ASSERT_EQ(result.meshes.size(), frames.size());
  double worst = 0;
  for (size_t f = 0; f < frames.size(); ++f) {
    ASSERT_TRUE(result.frames[f].ok) << result.frames[f].reason;
    for (size_t k = 0; k < fx.actor.markers.size(); ++k) {
      const Marker& m = fx.actor.markers[k];
      const Vec3 on_mesh =
          EvaluateSurfacePoint(m.point, fx.actor.neutral.F, result.meshes[f]);
      const double d = (on_mesh - frames[f].bundles.at(m.name)).norm();
      worst = std::max(worst, d);
      EXPECT_NEAR(result.frames[f].bundles[k].residual, d, 1e-9);
    }
  }
  EXPECT_LT(worst, 1e-6);
}

// Without the correction the RBF blend of shape weights does not pass
// through the bundles (the paper's remark); the correction is what does it.
TEST_P(LgiRbfSeeds, CorrectionIsWhatInterpolates) {
  LgiRbfOptions plain;
  plain.correct = false;
  const RbfFixture fx(GetParam(), /*jaw=*/false, plain);
  std::mt19937 rng(200 + GetParam());
  const std::vector<BundleFrame> frames = MixtureFrames(fx, 4, &rng);
  const SolveResult result = fx.rbf.SolveSequence(frames, {});
  double worst = 0;
  for (size_t f = 0; f < frames.size(); ++f) {
    ASSERT_TRUE(result.frames[f].ok);
    for (const BundleSolve& b : result.frames[f].bundles) {
      worst = std::max(worst, b.residual);
    }
  }
  EXPECT_GT(worst, 1e-3);
}

TEST_P(LgiRbfSeeds, NeutralBundlesGiveTheSkinnedNeutral) {
  const RbfFixture fx(GetParam(), /*jaw=*/true);
  const JawPose zero;
  JawPose open;
  open.open_deg = 6.0;
  open.lateral_deg = -1.5;
  std::vector<BundleFrame> frames;
  std::vector<JawPose> jaw = {zero, open};
  std::vector<MatX3d> expected;
  for (size_t f = 0; f < jaw.size(); ++f) {
    expected.push_back(Skin(*fx.actor.jaw_rig, jaw[f], fx.actor.neutral.V));
    frames.push_back(fx.Bundles(static_cast<int>(f) + 1, expected.back()));
  }
  const SolveResult result = fx.rbf.SolveSequence(frames, jaw);
  for (size_t f = 0; f < frames.size(); ++f) {
    ASSERT_TRUE(result.frames[f].ok) << result.frames[f].reason;
    EXPECT_LT((result.meshes[f] - expected[f]).cwiseAbs().maxCoeff(), 1e-6)
        << "frame " << f;
  }
}

TEST_P(LgiRbfSeeds, BadFrameRepeatsThePreviousGoodMesh) {
  const RbfFixture fx(GetParam(), /*jaw=*/false);
  std::mt19937 rng(300 + GetParam());
  const std::vector<BundleFrame> frames = MixtureFrames(fx, 3, &rng);
  const SolveResult result =
      fx.rbf.SolveSequence(frames, {}, {"", "tracking lost", ""});
  ASSERT_TRUE(result.frames[0].ok);
  EXPECT_FALSE(result.frames[1].ok);
  EXPECT_EQ(result.frames[1].reason, "tracking lost");
  EXPECT_EQ(result.summary.bad_frames, 1);
  EXPECT_EQ((result.meshes[1] - result.meshes[0]).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_GT((result.meshes[2] - result.meshes[0]).cwiseAbs().maxCoeff(), 0.0);
}

TEST_P(LgiRbfSeeds, SameResultForAnyThreadCount) {
  const RbfFixture fx(GetParam(), /*jaw=*/true);
  std::mt19937 rng(400 + GetParam());
  const std::vector<BundleFrame> frames = MixtureFrames(fx, 2, &rng);
  ExpectSameMeshesForAnyThreadCount(
      [&] { return fx.rbf.SolveSequence(frames, {}); });
}

INSTANTIATE_TEST_SUITE_P(Seeds, LgiRbfSeeds, ::testing::Values(1, 2, 3));

}  // namespace
}  // namespace hmc
