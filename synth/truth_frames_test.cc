#include "synth/truth_frames.h"

#include <algorithm>
#include <cmath>
#include <set>

#include <gtest/gtest.h>

#include "core/error.h"
#include "synth/marker_layout.h"

namespace hmc {
namespace {

struct Fixture {
  SynthActorOptions synth;
  std::unique_ptr<FaceModel> model;
  std::vector<Marker> markers;
  std::vector<DatasetEntry> plan;
};

Fixture Make(int seed, int holdout = 0, const std::string& holdout_units = "",
             const std::string& rig = "generator") {
  Fixture f;
  f.synth.seed = seed;
  f.synth.rig = rig;
  f.synth.holdout = holdout;
  f.synth.holdout_units = holdout_units;
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

// Active units of `a` that are (not) in `units`.
int CountIn(const Eigen::VectorXd& a, const std::vector<int>& units, bool in) {
  int count = 0;
  for (int k = 0; k < a.size(); ++k) {
    const bool member = std::find(units.begin(), units.end(), k) != units.end();
    if (a[k] != 0 && member == in) ++count;
  }
  return count;
}

class HoldoutFramesTest : public ::testing::TestWithParam<std::pair<int, int>> {};

TEST_P(HoldoutFramesTest, HeldoutFramesUseOnlyHeldOutUnits) {
  const auto [seed, holdout] = GetParam();
  const Fixture f = Make(seed, holdout);
  const std::vector<int> held = HeldOutUnits(*f.model, f.synth);
  ASSERT_EQ(static_cast<int>(held.size()), holdout);
  TruthFramesOptions options;
  options.kind = "heldout";
  options.frames = 150;
  options.seed = seed + 20;
  const auto frames = TruthActivations(*f.model, f.plan, options);
  ASSERT_EQ(frames.size(), 150u);
  std::set<int> sizes;
  std::set<int> seen;
  for (const Eigen::VectorXd& a : frames) {
    EXPECT_EQ(CountIn(a, held, false), 0);
    const int active = CountIn(a, held, true);
    EXPECT_GE(active, 1);
    EXPECT_LE(active, std::min(3, holdout));
    sizes.insert(active);
    for (int k = 0; k < a.size(); ++k) {
      if (a[k] == 0) continue;
      seen.insert(k);
      EXPECT_GE(a[k], options.min_activation);
      EXPECT_LE(a[k], 1.0);
    }
  }
  // 150 draws cover every count and every held-out unit.
  EXPECT_EQ(static_cast<int>(sizes.size()), std::min(3, holdout));
  EXPECT_EQ(std::vector<int>(seen.begin(), seen.end()), held);
}

TEST_P(HoldoutFramesTest, MixedFramesCombineHeldOutAndDatasetUnits) {
  const auto [seed, holdout] = GetParam();
  const Fixture f = Make(seed, holdout);
  const std::vector<int> held = HeldOutUnits(*f.model, f.synth);
  TruthFramesOptions options;
  options.kind = "mixed";
  options.frames = 150;
  options.seed = seed + 30;
  const auto frames = TruthActivations(*f.model, f.plan, options);
  ASSERT_EQ(frames.size(), 150u);
  for (const Eigen::VectorXd& a : frames) {
    const int from_held = CountIn(a, held, true);
    const int from_dataset = CountIn(a, held, false);
    EXPECT_GE(from_held, 1);
    EXPECT_LE(from_held, 3);
    EXPECT_GE(from_dataset, 1);
    EXPECT_GE(from_held + from_dataset, 2);
    EXPECT_LE(from_held + from_dataset, 5);
    EXPECT_GE(a.minCoeff(), 0.0);
    EXPECT_LE(a.maxCoeff(), 1.0);
  }
  // Combos and the performance's expression events stay on dataset units.
  options.kind = "combos";
  for (const Eigen::VectorXd& a : TruthActivations(*f.model, f.plan, options)) {
    EXPECT_EQ(CountIn(a, held, true), 0);
  }
}

INSTANTIATE_TEST_SUITE_P(SeedsAndCounts, HoldoutFramesTest,
                         ::testing::Values(std::make_pair(1, 1), std::make_pair(2, 3),
                                           std::make_pair(3, 5), std::make_pair(8, 8)));

TEST(TruthFramesTest, PerformanceDrawsHeldOutUnitsIntoItsEvents) {
  // Units the speech and blink tracks do not use, so only the random
  // expression events could reach them.
  const Fixture f = Make(3, 0, "AU04_brow_lowerer,AU09_nose_wrinkler,AU14_dimpler,"
                               "AU01_inner_brow_raiser_L,AU06_cheek_raiser_R");
  const std::vector<int> held = HeldOutUnits(*f.model, f.synth);
  ASSERT_EQ(held.size(), 5u);
  for (int seed : {1, 2, 3}) {
    TruthFramesOptions options;
    options.kind = "performance";
    options.frames = 60;
    options.seed = seed;
    const std::vector<Eigen::VectorXd> with_held =
        TruthActivations(*f.model, f.plan, options);
    ASSERT_EQ(with_held.size(), 60u);
    int frames_with_held = 0;
    for (size_t i = 0; i < with_held.size(); ++i) {
      if (CountIn(with_held[i], held, true) > 0) ++frames_with_held;
      EXPECT_GE(with_held[i].minCoeff(), 0.0);
      EXPECT_LE(with_held[i].maxCoeff(), 1.0);
      // Every change of activation is smooth apart from blinks.
      if (i > 0) {
        for (int k : held) {
          EXPECT_LE(std::abs(with_held[i][k] - with_held[i - 1][k]), 0.25)
              << seed << " frame " << i;
        }
      }
    }
    // A held-out event of at least 0.2 s hold lies inside the 2 s take.
    EXPECT_GE(frames_with_held, 6) << seed;
  }
}

// --holdout with the broad rig: the drawn units (never a jaw unit, the
// broad rig's own mouth_left/right among the candidates) leave the dataset,
// the performance draws them into its events, heldout and mixed frames use
// them, and every kind runs.
TEST(TruthFramesTest, BroadRigHoldsOutUnitsAsTheOtherRigs) {
  for (int seed : {2, 6, 12}) {
    SCOPED_TRACE(seed);
    const Fixture f = Make(seed, 4, "", "broad");
    const std::vector<int> held = HeldOutUnits(*f.model, f.synth);
    ASSERT_EQ(held.size(), 4u);
    for (int k : held) EXPECT_FALSE(f.model->units()[k].drives_jaw);
    EXPECT_EQ(UnitsNotInDataset(*f.model, f.plan), held);
    TruthFramesOptions options;
    options.kind = "performance";
    options.frames = 90;
    options.seed = seed + 1;
    int frames_with_held = 0;
    for (const Eigen::VectorXd& a : TruthActivations(*f.model, f.plan, options)) {
      frames_with_held += CountIn(a, held, true) > 0;
    }
    EXPECT_GE(frames_with_held, 6);
    options.kind = "heldout";
    for (const Eigen::VectorXd& a : TruthActivations(*f.model, f.plan, options)) {
      EXPECT_EQ(CountIn(a, held, false), 0);
      EXPECT_GE(CountIn(a, held, true), 1);
    }
    for (const std::string& kind : TruthFrameKinds()) {
      options.kind = kind;
      options.frames = 8;
      const TruthFrames frames = MakeTruthFrames(*f.model, f.markers, f.plan, options);
      EXPECT_FALSE(frames.activations.empty()) << kind;
    }
  }
  // The broad rig's extra units can be named.
  const Fixture f = Make(1, 0, "mouth_left,AU09_nose_wrinkler", "broad");
  EXPECT_EQ(HeldOutUnits(*f.model, f.synth).size(), 2u);
}

TEST(TruthFramesTest, EmptyPlanHoldsNothingOut) {
  const Fixture f = Make(5);
  for (const std::string kind : {"combos", "performance"}) {
    TruthFramesOptions options;
    options.kind = kind;
    options.frames = 60;
    options.seed = 9;
    EXPECT_EQ(TruthActivations(*f.model, {}, options),
              TruthActivations(*f.model, f.plan, options))
        << kind;
  }
  TruthFramesOptions options;
  options.kind = "heldout";
  EXPECT_THROW(TruthActivations(*f.model, {}, options), InputError);
}

TEST(TruthFramesTest, HeldOutKindsNeedHeldOutUnits) {
  const Fixture f = Make(2);
  for (const std::string kind : {"heldout", "mixed"}) {
    TruthFramesOptions options;
    options.kind = kind;
    EXPECT_TRUE(options.Check());
    EXPECT_TRUE(KindNeedsHeldOutUnits(kind));
    EXPECT_THROW(TruthActivations(*f.model, f.plan, options), InputError);
    EXPECT_THROW(MakeTruthFrames(*f.model, f.markers, f.plan, options), InputError);
  }
  EXPECT_FALSE(KindNeedsHeldOutUnits("combos"));
}

// Noise applies to every kind: bundles minus the noise-free bundles of the
// same seed are N(0, noise^2) per coordinate, and the draws do not depend on
// the level (one seed, two levels: the same draws scaled).
TEST(TruthFramesTest, NoiseOnEveryKind) {
  const Fixture f = Make(4, 3);
  for (const std::string& kind : TruthFrameKinds()) {
    TruthFramesOptions options;
    options.kind = kind;
    options.frames = 20;
    options.seed = 17;
    const TruthFrames exact = MakeTruthFrames(*f.model, f.markers, f.plan, options);
    std::vector<Vec3> draws_at_half;
    for (double noise : {0.5, 1.0}) {
      options.noise_mm = noise;
      const TruthFrames noisy = MakeTruthFrames(*f.model, f.markers, f.plan, options);
      ASSERT_EQ(noisy.bundles.size(), exact.bundles.size()) << kind;
      double sum = 0, sum_sq = 0;
      int n = 0;
      std::vector<Vec3> draws;
      for (size_t i = 0; i < exact.bundles.size(); ++i) {
        EXPECT_EQ(noisy.positions[i], exact.positions[i]);
        for (const auto& [name, p] : exact.bundles[i].bundles) {
          const Vec3 d = noisy.bundles[i].bundles.at(name) - p;
          draws.push_back(d);
          sum += d.sum();
          sum_sq += d.squaredNorm();
          n += 3;
        }
      }
      // Sampling error of a std estimate from n normal draws: sigma /
      // sqrt(2 n); of the mean: sigma / sqrt(n). Five of them.
      const double std_measured = std::sqrt(sum_sq / n);
      EXPECT_NEAR(std_measured, noise, 5 * noise / std::sqrt(2.0 * n)) << kind;
      EXPECT_NEAR(sum / n, 0.0, 5 * noise / std::sqrt(double(n))) << kind;
      if (noise == 0.5) {
        draws_at_half = draws;
      } else {
        ASSERT_EQ(draws.size(), draws_at_half.size());
        for (size_t j = 0; j < draws.size(); ++j) {
          EXPECT_NEAR((draws[j] - 2 * draws_at_half[j]).norm(), 0.0, 1e-9) << kind;
        }
      }
    }
  }
}

TEST(TruthFramesTest, HeldOutOptionsCheck) {
  TruthFramesOptions options;
  options.kind = "heldout";
  options.held_min_units = 0;
  EXPECT_FALSE(options.Check());
  options = TruthFramesOptions();
  options.held_min_units = 3;
  options.held_max_units = 2;
  EXPECT_FALSE(options.Check());
  options = TruthFramesOptions();
  options.kind = "mixed";
  options.min_units = 1;
  options.max_units = 1;
  EXPECT_FALSE(options.Check());
}

}  // namespace
}  // namespace hmc
