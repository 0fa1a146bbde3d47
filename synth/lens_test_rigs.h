// Rig options with the lenses other than the default Kannala-Brandt fisheye
// (core/camera.h), for the tests of every stage that projects: a narrow
// pinhole radial-tangential lens (configs/synth_shot_narrow.yaml, with a
// small k3) and a double-sphere fisheye. Header-only, tests only.
#pragma once

#include <vector>

#include "synth/helmet_rig.h"

namespace hmc {

inline std::vector<HelmetRigOptions> OtherLensRigOptions() {
  HelmetRigOptions narrow;
  narrow.model = "pinhole_radtan";
  narrow.focal_px = 710;
  narrow.k1 = -0.12;
  narrow.k2 = 0.02;
  narrow.k3 = 0.001;
  narrow.p1 = 0.0004;
  narrow.p2 = -0.0003;
  narrow.camera_distance = 180;
  HelmetRigOptions ds;
  ds.model = "double_sphere";
  ds.focal_px = 350;
  ds.xi = -0.15;
  ds.alpha = 0.58;
  return {narrow, ds};
}

}  // namespace hmc
