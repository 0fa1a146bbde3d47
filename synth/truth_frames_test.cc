#include "synth/truth_frames.h"

#include <cmath>

#include <gtest/gtest.h>

#include "synth/marker_layout.h"

namespace hmc {
namespace {

struct Fixture {
  SynthActorOptions synth;
  std::unique_ptr<FaceModel> model;
  std::vector<Marker> markers;
  std::vector<DatasetEntry> plan;
};

Fixture Make(int seed) {
  Fixture f;
  f.synth.seed = seed;
  f.synth.grid_u = 48;
  f.synth.grid_v = 40;
  f.model = std::make_unique<FaceModel>(f.synth);
  f.markers = LayoutMarkers(f.model->face(), seed, f.synth.marker_jitter_mm);
  f.plan = PlanDataset(*f.model, f.synth);
  return f;
}

TEST(TruthFramesTest, CombosAreFreshCombinationsOfTwoToFiveUnits) {
  for (int seed : {1, 2, 3}) {
    const Fixture f = Make(seed);
    TruthFramesOptions options;
    options.kind = "combos";
    options.frames = 200;
    options.seed = seed;
    const auto frames = TruthActivations(*f.model, f.plan, options);
    ASSERT_EQ(frames.size(), 200u);
    for (const Eigen::VectorXd& a : frames) {
      const int active = static_cast<int>((a.array() > 0).count());
      EXPECT_GE(active, 2);
      EXPECT_LE(active, 5);
      EXPECT_GE(a.minCoeff(), 0.0);
      EXPECT_LE(a.maxCoeff(), 1.0);
      for (const DatasetEntry& entry : f.plan) EXPECT_NE(entry.activations, a);
    }
    // Different seeds draw different frames; the same seed the same ones.
    TruthFramesOptions other = options;
    other.seed = seed + 10;
    EXPECT_NE(TruthActivations(*f.model, f.plan, other)[0], frames[0]);
    EXPECT_EQ(TruthActivations(*f.model, f.plan, options)[7], frames[7]);
  }
}

class TruthFramesSeedTest : public ::testing::TestWithParam<int> {};

TEST_P(TruthFramesSeedTest, PerformanceIsSmoothWithSpeechAndBlinks) {
  const Fixture f = Make(GetParam());
  TruthFramesOptions options;
  options.seed = GetParam();
  options.kind = "performance";
  options.frames = 300;  // 10 s at 30 fps
  const auto frames = TruthActivations(*f.model, f.plan, options);
  ASSERT_EQ(frames.size(), 300u);
  const int jaw = f.model->FindUnit("AU26_jaw_drop");
  const int blink = f.model->FindUnit("AU45_blink_L");
  double max_step = 0, max_jaw = 0;
  int blink_frames = 0, expressive_frames = 0;
  for (size_t i = 0; i < frames.size(); ++i) {
    EXPECT_GE(frames[i].minCoeff(), 0.0);
    EXPECT_LE(frames[i].maxCoeff(), 1.0);
    if (i > 0) {
      // Blinks are fast (a lid closes in ~3 frames); everything else is slow.
      Eigen::VectorXd step = (frames[i] - frames[i - 1]).cwiseAbs();
      step[blink] = step[f.model->FindUnit("AU45_blink_R")] = 0;
      max_step = std::max(max_step, step.maxCoeff());
    }
    max_jaw = std::max(max_jaw, frames[i][jaw]);
    blink_frames += frames[i][blink] > 0.5 ? 1 : 0;
    expressive_frames += (frames[i].array() > 0.2).count() >= 2 ? 1 : 0;
  }
  EXPECT_LT(max_step, 0.25);
  EXPECT_GT(max_jaw, 0.3);
  EXPECT_GT(blink_frames, 1);
  EXPECT_GT(expressive_frames, 30);
}

INSTANTIATE_TEST_SUITE_P(Seeds, TruthFramesSeedTest, ::testing::Values(4, 5, 6, 7));

TEST(TruthFramesTest, BundlesAreMarkersOnTheTruthPlusNoise) {
  const Fixture f = Make(5);
  TruthFramesOptions options;
  options.kind = "combos";
  options.frames = 30;
  options.seed = 8;
  const TruthFrames exact = MakeTruthFrames(*f.model, f.markers, f.plan, options);
  options.noise_mm = 0.5;
  const TruthFrames noisy = MakeTruthFrames(*f.model, f.markers, f.plan, options);
  ASSERT_EQ(exact.positions.size(), 30u);
  double sum_sq = 0;
  int n = 0;
  for (size_t i = 0; i < exact.positions.size(); ++i) {
    EXPECT_EQ(exact.bundles[i].frame, static_cast<int>(i) + 1);
    EXPECT_EQ(exact.jaw[i].frame, static_cast<int>(i) + 1);
    EXPECT_EQ(exact.positions[i], f.model->Evaluate(exact.activations[i]));
    EXPECT_EQ(exact.jaw[i].pose.ToArray(), f.model->JawPoseOf(exact.activations[i]).ToArray());
    ASSERT_EQ(exact.bundles[i].bundles.size(), f.markers.size());
    for (const Marker& m : f.markers) {
      const Vec3 truth = EvaluateSurfacePoint(m.point, f.model->neutral().F, exact.positions[i]);
      EXPECT_EQ(exact.bundles[i].bundles.at(m.name), truth);
      const Vec3 d = noisy.bundles[i].bundles.at(m.name) - truth;
      sum_sq += d.squaredNorm();
      n += 3;
    }
  }
  // Sample std of ~14000 draws: within a few percent of the requested 0.5.
  EXPECT_NEAR(std::sqrt(sum_sq / n), 0.5, 0.03);
}

TEST(TruthFramesTest, DatasetKindReplaysTheDataset) {
  const Fixture f = Make(6);
  TruthFramesOptions options;
  options.kind = "dataset";
  const TruthFrames frames = MakeTruthFrames(*f.model, f.markers, f.plan, options);
  ASSERT_EQ(frames.positions.size(), f.plan.size());
  for (size_t i = 0; i < f.plan.size(); i += 11) {
    EXPECT_EQ(frames.labels[i], f.plan[i].name);
    EXPECT_EQ(frames.positions[i], f.model->Evaluate(f.plan[i].activations));
  }
}

TEST(TruthFramesTest, OptionsCheck) {
  TruthFramesOptions options;
  EXPECT_TRUE(options.Check());
  options.kind = "random";
  EXPECT_FALSE(options.Check());
  options = TruthFramesOptions();
  options.max_units = 1;
  EXPECT_FALSE(options.Check());
  options = TruthFramesOptions();
  options.noise_mm = -0.1;
  EXPECT_FALSE(options.Check());
}

}  // namespace
}  // namespace hmc
