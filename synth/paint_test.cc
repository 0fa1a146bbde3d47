// The day's paint (synth/paint.h): offsets on the surface with the asked
// spread, the unpainted and rubbed-off dots, the same painting for the
// same seed.
#include "synth/paint.h"

#include <cmath>
#include <set>

#include <gtest/gtest.h>

#include "synth/synth_actor.h"

namespace hmc {
namespace {

Actor SmallActor(int seed) {
  SynthActorOptions options;
  options.seed = seed;
  options.grid_u = 64;
  options.grid_v = 52;
  options.dataset_inbetweens = false;
  options.dataset_combos = false;
  return SynthesizeActor(options);
}

TEST(Paint, OffsetsHaveTheAskedSpreadAndStayOnTheSurface) {
  for (const auto& [seed, jitter] : {std::pair{5, 1.0}, std::pair{17, 2.0}}) {
    const Actor actor = SmallActor(seed);
    PaintOptions options;
    options.jitter_mm = jitter;
    const PaintedDots painted = PaintDots(actor.neutral, actor.markers, options, seed);
    ASSERT_EQ(painted.markers.size(), actor.markers.size());
    double sum2 = 0;
    for (size_t k = 0; k < painted.markers.size(); ++k) {
      const SurfacePoint& p = painted.markers[k].point;
      ASSERT_GE(p.face, 0);
      EXPECT_NEAR(p.bary.sum(), 1.0, 1e-9);
      EXPECT_GE(p.bary.minCoeff(), -1e-12);
      const Vec3 a = EvaluateSurfacePoint(actor.markers[k].point, actor.neutral.F, actor.neutral.V);
      const Vec3 b = EvaluateSurfacePoint(p, actor.neutral.F, actor.neutral.V);
      sum2 += (b - a).squaredNorm();
    }
    // Two tangential axes of std `jitter`: E|offset|^2 = 2 jitter^2 (a
    // little less where the surface curves away); 155 dots: within 25 %.
    const double rms_per_axis = std::sqrt(sum2 / painted.markers.size() / 2);
    EXPECT_NEAR(rms_per_axis, jitter, 0.25 * jitter) << "seed " << seed;
    // The same seed paints the same day.
    const PaintedDots again = PaintDots(actor.neutral, actor.markers, options, seed);
    for (size_t k = 0; k < painted.markers.size(); ++k) {
      EXPECT_EQ(again.markers[k].point.face, painted.markers[k].point.face);
    }
  }
}

TEST(Paint, UnpaintedAndLostDots) {
  const Actor actor = SmallActor(9);
  PaintOptions options;
  options.missing = 3;
  options.lost_at = "12:2";
  ASSERT_TRUE(options.Check());
  const PaintedDots painted = PaintDots(actor.neutral, actor.markers, options, 9);
  EXPECT_EQ(painted.missing.size(), 3u);
  EXPECT_EQ(painted.markers.size(), actor.markers.size() - 3);
  EXPECT_EQ(painted.lost_frame, 12);
  ASSERT_EQ(painted.lost.size(), 2u);
  std::set<std::string> missing(painted.missing.begin(), painted.missing.end());
  for (const std::string& name : painted.lost) EXPECT_FALSE(missing.count(name)) << name;
  EXPECT_EQ(painted.At(11).size(), painted.markers.size());
  EXPECT_EQ(painted.At(12).size(), painted.markers.size() - 2);
  PaintOptions bad;
  bad.lost_at = "12";
  EXPECT_FALSE(bad.Check());
}

}  // namespace
}  // namespace hmc
