// Per-seed variation of the footage renderer's set (`hmc synth shot`'s
// `vary:` section; docs/footage.md, "Varied sets"): what changes from one
// real shoot to the next -- exposure and its drift over the shot,
// vignetting, skin albedo and specularity, dot size and darkness, blur,
// sensor noise -- drawn uniformly from ranges, deterministically from the
// shot's seed. Off by default (the built-in defaults render the same set
// for every seed); every configs/synth_shot_*.yaml preset turns it on.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/options.h"
#include "synth/footage.h"

namespace hmc {

struct ShotVariationOptions {
  bool on = false;                                    // draw the render options below from the seed
  std::vector<double> exposure = {0.75, 1.25};        // render.exposure is multiplied by a draw from this range
  std::vector<double> exposure_drift = {-0.2, 0.2};   // render.exposure_drift is set to a draw (relative change over the shot)
  std::vector<double> vignetting = {0.1, 0.5};        // render.vignetting is set to a draw
  std::vector<double> skin_albedo = {0.45, 0.7};      // render.skin_albedo is set to a draw
  std::vector<double> specular = {0, 0.15};           // render.specular is set to a draw
  std::vector<double> dot_radius = {0.85, 1.15};      // render.dot_radius is multiplied by a draw
  std::vector<double> dot_albedo = {0.04, 0.14};      // render.dot_albedo is set to a draw
  std::vector<double> defocus_px = {0, 0.6};          // a draw is added to render.defocus_px in quadrature (px)
  std::vector<double> read_noise = {0.5, 2};          // render.read_noise is multiplied by a draw
  std::vector<double> shot_noise = {0.5, 2};          // render.shot_noise is multiplied by a draw

  void Register(OptionFields* fields);
  bool Check() const;
};

// `render` with the drawn variation applied (unchanged when !vary.on). The
// draws come from a stream of `seed` of their own, in a fixed order, so the
// same seed and ranges always give the same set.
FootageRenderOptions VaryRender(const FootageRenderOptions& render,
                                const ShotVariationOptions& vary, uint64_t seed);

// The shot folder's variation.yaml (docs/formats.md, "Shot folder"): the
// seed and the varied render options' values as drawn.
std::string VariationYaml(const FootageRenderOptions& varied, uint64_t seed);

}  // namespace hmc
