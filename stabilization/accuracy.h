// Errors of estimated head poses and jaw poses against ground truth (the
// synthetic shot's head_from_helmet.csv and jaw.csv), for tests, the
// benchmark and the commands' --truth option (docs/stabilization.md).
#pragma once

#include <array>
#include <string>
#include <vector>

#include "core/frame_data.h"

namespace hmc {

// The head pose error of a frame is E = estimate * truth^-1 (head space to
// head space, the identity when exact): its rotation angle and the
// displacement it gives the head-space origin (the neutral's origin), i.e.
// |t_E|. RMS and max over the frames both files have.
struct PoseError {
  int frames = 0;
  double translation_rms_mm = 0;
  double rotation_rms_deg = 0;
  double translation_max_mm = 0;
  double rotation_max_deg = 0;
  std::string BriefReport() const;
};
PoseError ComparePoses(const std::vector<PoseFrame>& estimate,
                       const std::vector<PoseFrame>& truth);

// Per jaw parameter (open_deg, lateral_deg, protrude_mm) RMS and max error
// over the frames both have.
struct JawError {
  int frames = 0;
  std::array<double, 3> rms{}, max{};
  std::string BriefReport() const;
};
JawError CompareJaw(const std::vector<JawFrame>& estimate,
                    const std::vector<JawFrame>& truth);

}  // namespace hmc
