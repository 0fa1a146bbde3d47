// The picture options `hmc eval` and `hmc experiment` share (eval/error_pictures.h): truth |
// reconstruction | error heat-map panels rendered by hmc (core/render_mesh.h)
// with a colour bar. Registered at the caller's level, so the keys are
// image_width, image_height, heat_max_mm, color_map.
#pragma once

#include <cmath>
#include <string>

#include "core/logging.h"
#include "core/options.h"

namespace hmc {

struct PictureOptions {
  int image_width = 360;   // size of one picture panel (px)
  int image_height = 450;
  double heat_max_mm = 0.0;  // top of the heat-map scale (mm); 0: the largest
                             // face-region 95th percentile of the pictured
                             // frames
  std::string color_map = "viridis";  // heat-map colours

  void Register(OptionFields* fields) {
    fields->Add("image_width", &image_width, "picture panel width (px)");
    fields->Add("image_height", &image_height, "picture panel height (px)");
    fields->Add("heat_max_mm", &heat_max_mm,
                "top of the heat-map scale (mm); 0: the largest face-region "
                "95th percentile of the pictured frames");
    fields->Add("color_map", &color_map,
                "heat-map colours: viridis, inferno, turbo");
  }
  bool Check() const {
    if (image_width < 32 || image_height < 32) {
      spdlog::error("image_width and image_height must be >= 32");
      return false;
    }
    if (!(heat_max_mm >= 0) || !std::isfinite(heat_max_mm)) {
      spdlog::error("heat_max_mm must be >= 0");
      return false;
    }
    return true;
  }
};

}  // namespace hmc
