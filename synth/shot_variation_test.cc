#include "synth/shot_variation.h"

#include <cmath>

#include <gtest/gtest.h>

namespace hmc {
namespace {

bool In(double value, const std::vector<double>& range, double scale = 1) {
  return value >= scale * range[0] && value <= scale * range[1];
}

// Every varied option lies in its range (a scaled one: the base times it).
void ExpectInRanges(const FootageRenderOptions& base, const FootageRenderOptions& varied,
                    const ShotVariationOptions& vary) {
  EXPECT_TRUE(In(varied.exposure, vary.exposure, base.exposure)) << varied.exposure;
  EXPECT_TRUE(In(varied.exposure_drift, vary.exposure_drift)) << varied.exposure_drift;
  EXPECT_TRUE(In(varied.vignetting, vary.vignetting)) << varied.vignetting;
  EXPECT_TRUE(In(varied.skin_albedo, vary.skin_albedo)) << varied.skin_albedo;
  EXPECT_TRUE(In(varied.specular, vary.specular)) << varied.specular;
  EXPECT_TRUE(In(varied.dot_radius, vary.dot_radius, base.dot_radius)) << varied.dot_radius;
  EXPECT_TRUE(In(varied.dot_albedo, vary.dot_albedo)) << varied.dot_albedo;
  const double added = std::sqrt(std::max(
      0.0, varied.defocus_px * varied.defocus_px - base.defocus_px * base.defocus_px));
  EXPECT_TRUE(In(added, {vary.defocus_px[0] - 1e-9, vary.defocus_px[1] + 1e-9})) << added;
  EXPECT_TRUE(In(varied.read_noise, vary.read_noise, base.read_noise)) << varied.read_noise;
  EXPECT_TRUE(In(varied.shot_noise, vary.shot_noise, base.shot_noise)) << varied.shot_noise;
  EXPECT_TRUE(varied.Check());
  // What vary does not touch stays.
  EXPECT_EQ(varied.motion_blur_samples, base.motion_blur_samples);
  EXPECT_EQ(varied.transfer, base.transfer);
  EXPECT_EQ(varied.light_power, base.light_power);
}

TEST(ShotVariationTest, OffLeavesTheRenderOptions) {
  FootageRenderOptions base;
  base.read_noise = 3;
  const ShotVariationOptions vary;  // on = false
  const FootageRenderOptions out = VaryRender(base, vary, 17);
  EXPECT_EQ(out.exposure, base.exposure);
  EXPECT_EQ(out.read_noise, base.read_noise);
  EXPECT_EQ(out.skin_albedo, base.skin_albedo);
  EXPECT_EQ(out.dot_radius, base.dot_radius);
  EXPECT_EQ(VariationYaml(out, 17), VariationYaml(base, 17));
}

TEST(ShotVariationTest, SeedsDrawDifferentSetsInRangeAndReproducibly) {
  FootageRenderOptions base;  // a preset's values: the scaled ranges multiply them
  base.dot_radius = 0.7;
  base.defocus_px = 0.8;
  base.read_noise = 3;
  ShotVariationOptions vary;
  vary.on = true;
  ASSERT_TRUE(vary.Check());
  for (uint64_t seed : {1u, 2u, 9101u, 424242u}) {
    const FootageRenderOptions a = VaryRender(base, vary, seed);
    ExpectInRanges(base, a, vary);
    EXPECT_EQ(VariationYaml(a, seed), VariationYaml(VaryRender(base, vary, seed), seed))
        << "seed " << seed << " is not reproducible";
    const FootageRenderOptions b = VaryRender(base, vary, seed + 1);
    // Each quantity is a continuous draw: two seeds differ in every one.
    EXPECT_NE(a.exposure, b.exposure);
    EXPECT_NE(a.exposure_drift, b.exposure_drift);
    EXPECT_NE(a.vignetting, b.vignetting);
    EXPECT_NE(a.skin_albedo, b.skin_albedo);
    EXPECT_NE(a.specular, b.specular);
    EXPECT_NE(a.dot_radius, b.dot_radius);
    EXPECT_NE(a.dot_albedo, b.dot_albedo);
    EXPECT_NE(a.defocus_px, b.defocus_px);
    EXPECT_NE(a.read_noise, b.read_noise);
    EXPECT_NE(a.shot_noise, b.shot_noise);
  }
  // Over many seeds the draws spread over their ranges, not one corner.
  double lo = 1e9, hi = -1e9;
  for (uint64_t seed = 0; seed < 200; ++seed) {
    const double v = VaryRender(base, vary, seed).vignetting;
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  const double width = vary.vignetting[1] - vary.vignetting[0];
  EXPECT_LT(lo, vary.vignetting[0] + 0.1 * width);
  EXPECT_GT(hi, vary.vignetting[1] - 0.1 * width);
}

TEST(ShotVariationTest, ExposureDriftsLinearlyOverTheShot) {
  FootageRenderOptions options;
  options.exposure = 0.8;
  options.exposure_drift = -0.25;
  EXPECT_DOUBLE_EQ(options.ExposureAt(0), 0.8);
  EXPECT_DOUBLE_EQ(options.ExposureAt(1), 0.8 * 0.75);
  EXPECT_DOUBLE_EQ(options.ExposureAt(0.5), 0.8 * 0.875);
}

TEST(ShotVariationTest, RefusesBadRanges) {
  ShotVariationOptions vary;
  vary.on = true;
  vary.skin_albedo = {0.7, 0.4};  // lo > hi
  EXPECT_FALSE(vary.Check());
  vary.skin_albedo = {0.4};
  EXPECT_FALSE(vary.Check());
  vary.skin_albedo = {0.4, 1.5};  // reflectance above 1
  EXPECT_FALSE(vary.Check());
  vary = ShotVariationOptions();
  vary.exposure = {0, 1};
  EXPECT_FALSE(vary.Check());
}

}  // namespace
}  // namespace hmc
