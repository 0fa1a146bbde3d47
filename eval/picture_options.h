// The picture options `hmc eval` and `hmc experiment` share (eval/error_pictures.h): truth |
// reconstruction | error heat-map panels rendered by hmc (core/render_mesh.h)
// with a colour bar. Registered at the caller's level, so the keys are
// image_width, image_height, heat_max_mm, color_map.
#pragma once

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
    fields->Add("image_width", &image_width, "picture panel width (px)").AtLeast(32);
    fields->Add("image_height", &image_height, "picture panel height (px)").AtLeast(32);
    fields->Add("heat_max_mm", &heat_max_mm,
                "top of the heat-map scale (mm); 0: the largest face-region "
                "95th percentile of the pictured frames")
        .AtLeast(0);
    fields->Add("color_map", &color_map,
                "heat-map colours: viridis, inferno, turbo");
  }
  bool Check() const {
    CHECK_OPTION_LIMITS();
    return true;
  }
};

}  // namespace hmc
