#include "synth/performance.h"

#include <cmath>

#include <gtest/gtest.h>

#include "synth/synth_actor.h"

namespace hmc {
namespace {

double AngleDeg(const Rigid3& t) {
  return Eigen::AngleAxisd(t.linear()).angle() * 180 / M_PI;
}

TEST(PerformanceTest, SlipIsBoundedSlowAndVibrationSmall) {
  for (int seed : {1, 2, 3}) {
    PerformanceOptions options;
    options.seed = seed;
    options.frames = 300;
    options.vibration_mm = 0;
    options.vibration_deg = 0;
    double max_t = 0, max_r = 0;
    for (int f = 0; f < options.frames; ++f) {
      const Rigid3 pose = HeadFromHelmetAt(options, f / options.fps);
      max_t = std::max(max_t, pose.translation().norm());
      max_r = std::max(max_r, AngleDeg(pose));
      // Slow: under 0.1 mm per frame at 30 fps (a slip of slip_mm takes
      // many frames).
      const Rigid3 next = HeadFromHelmetAt(options, (f + 1) / options.fps);
      EXPECT_LT((next.translation() - pose.translation()).norm(), 0.1);
    }
    EXPECT_LE(max_t, options.slip_mm + 1e-9);
    EXPECT_LE(max_r, options.slip_deg + 1e-9);
    EXPECT_GT(max_t, 0.3 * options.slip_mm) << "the head must actually slip";
    // Vibration: the difference with and without it stays within its amplitude
    // and changes sign quickly (high frequency).
    PerformanceOptions vibrating = options;
    vibrating.vibration_mm = 0.12;
    vibrating.vibration_deg = 0.04;
    int sign_changes = 0;
    double previous = 0;
    for (int f = 0; f < options.frames; ++f) {
      const double t = f / options.fps;
      const Vec3 d = HeadFromHelmetAt(vibrating, t).translation() -
                     HeadFromHelmetAt(options, t).translation();
      EXPECT_LE(d.norm(), vibrating.vibration_mm + 1e-9);
      if (f > 0 && d.x() * previous < 0) ++sign_changes;
      previous = d.x();
    }
    EXPECT_GT(sign_changes, options.frames / 10);
  }
}

TEST(PerformanceTest, DeterministicBySeedWithExpressionsAndBlinks) {
  SynthActorOptions synth;
  synth.grid_u = 48;
  synth.grid_v = 40;
  const FaceModel model(synth);
  PerformanceOptions options;
  options.frames = 150;
  const ShotPerformance a = MakePerformance(model, options);
  const ShotPerformance b = MakePerformance(model, options);
  options.seed = 2;
  const ShotPerformance c = MakePerformance(model, options);
  ASSERT_EQ(a.activations.size(), 150u);
  double diff_same = 0, diff_other = 0;
  for (int f = 0; f < 150; ++f) {
    diff_same += (a.activations[f] - b.activations[f]).norm() +
                 (a.head_from_helmet[f].matrix() - b.head_from_helmet[f].matrix()).norm();
    diff_other += (a.activations[f] - c.activations[f]).norm();
  }
  EXPECT_EQ(diff_same, 0);
  EXPECT_GT(diff_other, 0);
  // Speech moves the jaw, blinks close the eyes, several units overlap.
  const int jaw = model.FindUnit("AU26_jaw_drop");
  const int blink = model.FindUnit("AU45_blink_L");
  double max_jaw = 0, max_blink = 0;
  int max_active = 0;
  for (const Eigen::VectorXd& act : a.activations) {
    max_jaw = std::max(max_jaw, act[jaw]);
    max_blink = std::max(max_blink, act[blink]);
    max_active = std::max(max_active, static_cast<int>((act.array() > 0.05).count()));
    EXPECT_GE(act.minCoeff(), 0);
    EXPECT_LE(act.maxCoeff(), 1);
  }
  EXPECT_GT(max_jaw, 0.1);
  EXPECT_GT(max_blink, 0.5);
  EXPECT_GE(max_active, 3);
}

// Between frames the activations follow a smooth curve through them: the
// frames themselves exactly, a trajectory quadratic in time exactly (so a
// shutter centred on a frame averages to its state plus a s^2 / 24, not to
// the kinked line's 0.075 second differences), never outside the two
// frames around, and the ends held.
TEST(PerformanceTest, ActivationsBetweenFramesAreSmoothThroughTheFrames) {
  ShotPerformance p;
  for (int f = 0; f < 10; ++f) {
    Eigen::VectorXd a(3);
    a << 0.01 * f * f, 0.1 * f, (f >= 4 ? 0.9 : 0.1);  // quadratic, linear, a step
    p.activations.push_back(a);
  }
  for (int f = 0; f < 10; ++f) {
    EXPECT_EQ((ActivationsAt(p, f) - p.activations[f]).norm(), 0) << f;
  }
  for (double t : {2.25, 3.5, 5.875, 7.1}) {
    const Eigen::VectorXd a = ActivationsAt(p, t);
    EXPECT_NEAR(a[0], 0.01 * t * t, 1e-12) << t;
    EXPECT_NEAR(a[1], 0.1 * t, 1e-12) << t;
    const int f = static_cast<int>(std::floor(t));
    EXPECT_GE(a[2], std::min(p.activations[f][2], p.activations[f + 1][2])) << t;
    EXPECT_LE(a[2], std::max(p.activations[f][2], p.activations[f + 1][2])) << t;
  }
  // Five samples over half a frame around frame 5: their mean is the
  // frame's state plus the smooth curve's own shutter term, a'' E[tau^2]/2.
  Eigen::VectorXd mean = Eigen::VectorXd::Zero(3);
  double tau2 = 0;
  for (int j = 0; j < 5; ++j) {
    const double tau = (j / 4.0 - 0.5) * 0.5;
    mean += ActivationsAt(p, 5 + tau) / 5;
    tau2 += tau * tau / 5;
  }
  EXPECT_NEAR(mean[0], 0.25 + 0.02 * tau2 / 2, 1e-12);
  EXPECT_NEAR(mean[1], 0.5, 1e-12);
  EXPECT_EQ(ActivationsAt(p, 9.5), p.activations[9]);  // past the last frame: held
}

}  // namespace
}  // namespace hmc
