#include "stabilization/jaw_fit.h"

#include <cmath>
#include <cstdio>
#include <random>
#include <tuple>

#include <ceres/ceres.h>
#include <gtest/gtest.h>

#include "core/error.h"
#include "core/jaw_estimate.h"
#include "stabilization/accuracy.h"
#include "stabilization/jaw_cost.h"
#include "stabilization/shot_test_util.h"
#include "stabilization/stabilize.h"

namespace hmc {
namespace {

const SmallActor& Actor1() {
  static const SmallActor actor = MakeSmallActor(1);
  return actor;
}

TEST(JawCostTest, JacobianMatchesFiniteDifferences) {
  const SmallActor& a = Actor1();
  ASSERT_TRUE(a.actor.jaw_rig.has_value());
  const JawRig& rig = *a.actor.jaw_rig;
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> open(-2, 25), lateral(-6, 6), protrude(-3, 5);
  std::normal_distribution<double> normal(0, 3);
  for (int trial = 0; trial < 20; ++trial) {
    const int k = trial % a.markers.num_markers;
    const Vec3 u = a.markers.neutral.row(k).transpose() + Vec3(normal(rng), normal(rng), normal(rng));
    const Vec3 p = u + Vec3(normal(rng), normal(rng), normal(rng));
    const Vec3 m(normal(rng), normal(rng), normal(rng));
    // Autodiff against Ceres' central differences of the same functor,
    // through CostFunction::Evaluate on plain arrays. (ceres::GradientChecker
    // hands Eigen matrices allocated inside the Ceres library to this
    // binary, which ASan reports as a mismatched aligned free.)
    std::unique_ptr<ceres::CostFunction> cost(JawMarkerCost::Create(rig, p, &u, 0.7, m));
    ceres::NumericDiffCostFunction<JawMarkerCost, ceres::CENTRAL, 3, 3> numeric(
        new JawMarkerCost(rig, p, &u, 0.7, m));
    double theta[3] = {open(rng), lateral(rng), protrude(rng)};
    const double* parameters[1] = {theta};
    double r_auto[3], r_numeric[3], j_auto[9], j_numeric[9];
    double* jac_auto[1] = {j_auto};
    double* jac_numeric[1] = {j_numeric};
    ASSERT_TRUE(cost->Evaluate(parameters, r_auto, jac_auto));
    ASSERT_TRUE(numeric.Evaluate(parameters, r_numeric, jac_numeric));
    for (int i = 0; i < 9; ++i) {
      EXPECT_NEAR(j_auto[i], j_numeric[i], 1e-6 * (1 + std::abs(j_numeric[i]))) << trial << " " << i;
    }
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(r_auto[i], r_numeric[i], 1e-12);
  }
}

TEST(JawCostTest, ResidualIsZeroAtTheSkinnedPosition) {
  // The functor's skinning is MarkerModel::Skin with JawRig::Transform.
  const SmallActor& a = Actor1();
  const JawRig& rig = *a.actor.jaw_rig;
  const JawPose pose{14.0, -3.5, 1.25};
  const Rigid3 t = rig.Transform(pose);
  for (int k = 0; k < a.markers.num_markers; k += 7) {
    const Vec3 u = a.markers.neutral.row(k).transpose() + Vec3(0.3, -0.2, 0.5);
    const Vec3 p = a.markers.Skin(k, t, u);
    const JawMarkerCost cost(rig, p, &u, a.markers.jaw_weight[k],
                             a.markers.jaw_moment.row(k).transpose());
    const std::array<double, 3> theta = pose.ToArray();
    double r[3];
    cost(theta.data(), r);
    EXPECT_LT(Vec3(r[0], r[1], r[2]).norm(), 1e-10);
    EXPECT_LT((a.markers.Unskin(k, t, p) - u).norm(), 1e-10);
  }
}

// On stabilized bundles (the pipeline's input) of 3 actors, noise-free and
// at 0.2 mm: the targets.
class JawAccuracy : public ::testing::TestWithParam<std::tuple<int, double>> {};

TEST_P(JawAccuracy, JawPoseMatchesTheTruth) {
  const auto [seed, noise] = GetParam();
  const SmallActor a = MakeSmallActor(seed);
  PerformanceOptions perf;
  perf.seed = seed + 20;
  perf.frames = 60;
  perf.jaw_activity = 0.6;
  const ShotTruth shot = MakeShotTruth(a, perf, noise);
  const StabilizeOutput stabilized = RunStabilize(a.markers, shot.helmet, StabilizeOptions());
  const JawOutput out = RunJaw(a.actor, a.markers, stabilized.bundles, JawOptions());
  EXPECT_EQ(out.num_ok, perf.frames);
  const JawError error = CompareJaw(out.JawFrames(), shot.jaw);
  const double degrees = noise == 0 ? 0.2 : 0.5, mm = noise == 0 ? 0.1 : 0.3;
  EXPECT_LT(error.rms[0], degrees) << error.BriefReport();
  EXPECT_LT(error.rms[1], degrees) << error.BriefReport();
  EXPECT_LT(error.rms[2], mm) << error.BriefReport();
}

INSTANTIATE_TEST_SUITE_P(SeedsAndNoise, JawAccuracy,
                         ::testing::Combine(::testing::Values(1, 2, 3),
                                            ::testing::Values(0.0, 0.2)));

TEST(JawFitTest, FramesWithoutJawMarkersAreInterpolatedAndFlagged) {
  const SmallActor& a = Actor1();
  PerformanceOptions perf;
  perf.frames = 12;
  ShotTruth shot = MakeShotTruth(a, perf, 0.0);
  JawOptions options;
  options.smoothness = 0;
  const std::vector<int> jaw = JawMarkers(a.markers, a.actor, options);
  ASSERT_GE(static_cast<int>(jaw.size()), options.min_jaw_markers);
  for (int k : jaw) shot.head[5].bundles.erase(a.markers.names[k]);
  shot.head[6].bundles.clear();
  const JawOutput out = RunJaw(a.actor, a.markers, shot.head, options);
  EXPECT_EQ(out.num_interpolated, 2);
  EXPECT_FALSE(out.frames[5].ok);
  EXPECT_FALSE(out.frames[6].ok);
  EXPECT_NE(out.frames[5].reason.find("jaw markers"), std::string::npos);
  const std::array<double, 3> before = out.frames[4].pose.ToArray();
  const std::array<double, 3> after = out.frames[7].pose.ToArray();
  const std::array<double, 3> f5 = out.frames[5].pose.ToArray();
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(f5[i], before[i] + (after[i] - before[i]) / 3, 1e-12);
}

// Jaw markers lost for a stretch, and at its two ends only a few left,
// named wrongly (8 mm off): those end fits rest on too few markers and must
// not anchor the stretch's interpolation (jaw_fit.h). Compared with the
// same shot without the rule, against the true jaw.
TEST(JawFitTest, FitsOnTooFewJawMarkersDoNotAnchorTheInterpolation) {
  const SmallActor& a = Actor1();
  for (int seed : {1, 2}) {
    PerformanceOptions perf;
    perf.frames = 30;
    perf.seed = seed;
    ShotTruth shot = MakeShotTruth(a, perf, 0.0);
    JawOptions options;
    options.min_marker_fraction = 0.75;  // the rule under test (off by default)
    const std::vector<int> jaw = JawMarkers(a.markers, a.actor, options);
    ASSERT_GE(jaw.size() * options.min_marker_fraction, options.min_jaw_markers + 1.0);
    for (int f = 12; f <= 15; ++f) {
      for (int k : jaw) shot.head[f].bundles.erase(a.markers.names[k]);
    }
    for (int f : {11, 16}) {  // min_jaw_markers left, named wrongly: 8 mm off
      for (size_t i = 0; i < jaw.size(); ++i) {
        const std::string& name = a.markers.names[jaw[i]];
        if (static_cast<int>(i) >= options.min_jaw_markers) {
          shot.head[f].bundles.erase(name);
        } else {
          shot.head[f].bundles[name] += Vec3(0, -8, 2);
        }
      }
    }
    const JawOutput out = RunJaw(a.actor, a.markers, shot.head, options);
    JawOptions trusting = options;
    trusting.min_marker_fraction = 0;
    trusting.max_residual_ratio = 0;
    const JawOutput trusted = RunJaw(a.actor, a.markers, shot.head, trusting);
    for (int f : {11, 16}) {
      EXPECT_FALSE(out.frames[f].ok) << f;
      EXPECT_NE(out.frames[f].reason.find("not trusted"), std::string::npos) << out.frames[f].reason;
      EXPECT_TRUE(trusted.frames[f].ok) << f;
    }
    double sq = 0, sq_trusted = 0;
    for (int f = 11; f <= 16; ++f) {
      const double truth = shot.jaw[f].pose.open_deg;
      sq += std::pow(out.frames[f].pose.open_deg - truth, 2);
      sq_trusted += std::pow(trusted.frames[f].pose.open_deg - truth, 2);
    }
    std::printf("seed %d: open RMS over the stretch %.3f deg, trusting the end fits %.3f\n", seed,
                std::sqrt(sq / 6), std::sqrt(sq_trusted / 6));
    EXPECT_LT(std::sqrt(sq / 6), 0.5 * std::sqrt(sq_trusted / 6)) << "seed " << seed;
    // The other frames are fitted as before.
    for (int f : {3, 25}) {
      EXPECT_TRUE(out.frames[f].ok);
      EXPECT_NEAR(out.frames[f].pose.open_deg, shot.jaw[f].pose.open_deg, 0.05) << f;
    }
  }
}

TEST(JawFitTest, AnActorWithoutAJawRigGetsAClearMessage) {
  SmallActor a = MakeSmallActor(2);
  a.actor.jaw_rig.reset();
  a.markers = ComputeMarkerModel(a.actor);
  try {
    RunJaw(a.actor, a.markers, {}, JawOptions());
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("no jaw rig"), std::string::npos) << e.what();
  }
}

// An actor without a jaw rig (docs/formats.md, "An estimated jaw rig"):
// the generator actor's rig and its shapes' jaw poses removed, the rig
// estimated from the dataset's jaw shapes, against the true rig: the
// hinge's direction, the pivot's distance from the true hinge line, the
// shapes' jaw poses, and the jaw stage on the true head-space bundles.
class JawRigEstimation : public ::testing::TestWithParam<std::tuple<int, bool>> {};

TEST_P(JawRigEstimation, RecoversTheRigAndTheJawStageWithIt) {
  const auto [seed, full_dataset] = GetParam();
  SynthActorOptions options;
  options.seed = seed;
  options.grid_u = 24;
  options.grid_v = 20;
  options.dataset_inbetweens = full_dataset;
  options.dataset_combos = full_dataset;
  const SmallActor a = MakeTestActor(options);
  ASSERT_TRUE(a.actor.jaw_rig.has_value());
  const JawRig& truth = *a.actor.jaw_rig;
  Actor stripped = a.actor;
  stripped.jaw_rig.reset();
  for (Shape& shape : stripped.shapes) shape.jaw = JawPose();
  const std::optional<JawRigEstimate> estimate = EstimateJawRig(stripped);
  ASSERT_TRUE(estimate.has_value());
  const JawRig& rig = estimate->rig;
  const double hinge_deg =
      std::acos(std::min(1.0, rig.axes.col(0).dot(truth.axes.col(0)))) * 180 / M_PI;
  const double vertical_deg =
      std::acos(std::min(1.0, rig.axes.col(1).dot(truth.axes.col(1)))) * 180 / M_PI;
  const Vec3 offset = truth.pivot - rig.pivot;
  const double pivot_mm = (offset - offset.dot(rig.axes.col(0)) * rig.axes.col(0)).norm();
  double pose_error = 0;
  for (size_t n = 0; n < stripped.shapes.size(); ++n) {
    const std::array<double, 3> e = estimate->shape_poses[n].ToArray();
    const std::array<double, 3> t = a.actor.shapes[n].jaw.ToArray();
    for (int i = 0; i < 3; ++i) pose_error = std::max(pose_error, std::abs(e[i] - t[i]));
  }
  Actor estimated = stripped;
  ApplyJawRigEstimate(*estimate, &estimated);
  const MarkerModel model = ComputeMarkerModel(estimated);
  PerformanceOptions perf;
  perf.seed = seed + 20;
  perf.frames = 40;
  perf.jaw_activity = 0.6;
  const ShotTruth shot = MakeShotTruth(a, perf, 0.0);
  const JawError with_estimate =
      CompareJaw(RunJaw(estimated, model, shot.head, JawOptions()).JawFrames(), shot.jaw);
  const JawError with_truth =
      CompareJaw(RunJaw(a.actor, a.markers, shot.head, JawOptions()).JawFrames(), shot.jaw);
  RecordProperty("estimate", estimate->Describe());
  RecordProperty("jaw_stage", with_estimate.BriefReport());
  EXPECT_LT(hinge_deg, 0.5);
  EXPECT_LT(vertical_deg, 0.5);
  EXPECT_LT(pivot_mm, 0.5);
  if (!full_dataset) {
    // The units alone: their jaw poses (degrees and millimetres) and the
    // jaw stage's noise-free targets (docs/stabilization.md: 0.2 deg and
    // 0.1 mm), as with the true rig.
    EXPECT_LT(pose_error, 0.2);
    EXPECT_LT(with_estimate.rms[0], 0.2) << with_estimate.BriefReport();
    EXPECT_LT(with_estimate.rms[1], 0.2) << with_estimate.BriefReport();
    EXPECT_LT(with_estimate.rms[2], 0.1) << with_estimate.BriefReport();
  } else {
    // With combinations, whose other units move the chin's skin too, their
    // fitted jaw poses are up to ~0.5 off and the jaw stage's protrusion
    // misses the noise-free 0.1 mm on some seeds (docs/formats.md, "An
    // estimated jaw rig"): held to the stage's 0.2 mm-noise targets.
    EXPECT_LT(pose_error, 1.0);
    EXPECT_LT(with_estimate.rms[0], 0.5) << with_estimate.BriefReport();
    EXPECT_LT(with_estimate.rms[1], 0.5) << with_estimate.BriefReport();
    EXPECT_LT(with_estimate.rms[2], 0.3) << with_estimate.BriefReport();
  }
  EXPECT_LT(with_truth.rms[2], 0.1) << with_truth.BriefReport();
}

INSTANTIATE_TEST_SUITE_P(SeedsAndDatasets, JawRigEstimation,
                         ::testing::Combine(::testing::Values(1, 2, 3),
                                            ::testing::Values(false, true)));

}  // namespace
}  // namespace hmc
