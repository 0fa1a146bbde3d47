#include "synth/shot_variation.h"

#include <cmath>

#include <fmt/format.h>

#include "synth/synth_random.h"

namespace hmc {

void ShotVariationOptions::Register(OptionFields* fields) {
  fields->SetGroup("vary");
  fields->Add("on", &on,
              "draw the render options below from the seed, each uniformly in its range [lo, hi] "
              "(docs/footage.md, \"Varied sets\")");
  fields->Add("exposure", &exposure, "render.exposure is multiplied by a draw from this range");
  fields->Add("exposure_drift", &exposure_drift,
              "render.exposure_drift (relative change over the shot) is set to a draw");
  fields->Add("vignetting", &vignetting, "render.vignetting is set to a draw");
  fields->Add("skin_albedo", &skin_albedo, "render.skin_albedo is set to a draw");
  fields->Add("specular", &specular, "render.specular is set to a draw");
  fields->Add("dot_radius", &dot_radius, "render.dot_radius is multiplied by a draw");
  fields->Add("dot_albedo", &dot_albedo, "render.dot_albedo is set to a draw");
  fields->Add("defocus_px", &defocus_px,
              "a draw is added to render.defocus_px in quadrature (px)");
  fields->Add("read_noise", &read_noise, "render.read_noise is multiplied by a draw");
  fields->Add("shot_noise", &shot_noise, "render.shot_noise is multiplied by a draw");
  fields->SetGroup("");
}

namespace {

bool RangeIn(const std::vector<double>& range, double lo, double hi) {
  return range.size() == 2 && range[0] >= lo && range[0] <= range[1] && range[1] <= hi;
}

}  // namespace

bool ShotVariationOptions::Check() const {
  CHECK_OPTION(RangeIn(exposure, 0.01, 10));
  CHECK_OPTION(RangeIn(exposure_drift, -0.9, 10));
  CHECK_OPTION(RangeIn(vignetting, 0, 1));
  CHECK_OPTION(RangeIn(skin_albedo, 0, 1));
  CHECK_OPTION(RangeIn(specular, 0, 1));
  CHECK_OPTION(RangeIn(dot_radius, 0.1, 10));
  CHECK_OPTION(RangeIn(dot_albedo, 0, 1));
  CHECK_OPTION(RangeIn(defocus_px, 0, 10));
  CHECK_OPTION(RangeIn(read_noise, 0, 10));
  CHECK_OPTION(RangeIn(shot_noise, 0, 10));
  return true;
}

FootageRenderOptions VaryRender(const FootageRenderOptions& render,
                                const ShotVariationOptions& vary, uint64_t seed) {
  FootageRenderOptions out = render;
  if (!vary.on) return out;
  SynthRandom rng = SynthRandom::Stream(seed, 0x5E7);
  auto draw = [&rng](const std::vector<double>& range) {
    return rng.Uniform(range[0], range[1]);
  };
  // The order of the draws is part of the format: a new quantity goes last.
  out.exposure *= draw(vary.exposure);
  out.exposure_drift = draw(vary.exposure_drift);
  out.vignetting = draw(vary.vignetting);
  out.skin_albedo = draw(vary.skin_albedo);
  out.specular = draw(vary.specular);
  out.dot_radius *= draw(vary.dot_radius);
  out.dot_albedo = draw(vary.dot_albedo);
  out.defocus_px = std::hypot(out.defocus_px, draw(vary.defocus_px));
  out.read_noise *= draw(vary.read_noise);
  out.shot_noise *= draw(vary.shot_noise);
  return out;
}

std::string VariationYaml(const FootageRenderOptions& varied, uint64_t seed) {
  return fmt::format(
      "# The render options drawn by `vary:` from the seed (docs/formats.md, \"Shot folder\").\n"
      "seed: {}\n"
      "render:\n"
      "  exposure: {:.17g}\n"
      "  exposure_drift: {:.17g}\n"
      "  vignetting: {:.17g}\n"
      "  skin_albedo: {:.17g}\n"
      "  specular: {:.17g}\n"
      "  dot_radius: {:.17g}\n"
      "  dot_albedo: {:.17g}\n"
      "  defocus_px: {:.17g}\n"
      "  read_noise: {:.17g}\n"
      "  shot_noise: {:.17g}\n",
      seed, varied.exposure, varied.exposure_drift, varied.vignetting, varied.skin_albedo,
      varied.specular, varied.dot_radius, varied.dot_albedo, varied.defocus_px,
      varied.read_noise, varied.shot_noise);
}

}  // namespace hmc
