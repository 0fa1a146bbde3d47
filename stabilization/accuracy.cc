#include "stabilization/accuracy.h"

#include <algorithm>
#include <cmath>
#include <map>

#include <fmt/format.h>

#include "core/error_stats.h"

namespace hmc {

std::string PoseError::BriefReport() const {
  return fmt::format(
      "head pose vs truth over {} frames: translation RMS {:.4f} mm (max {:.4f}), rotation "
      "RMS {:.5f} deg (max {:.5f})",
      frames, translation_rms_mm, translation_max_mm, rotation_rms_deg, rotation_max_deg);
}

PoseError ComparePoses(const std::vector<PoseFrame>& estimate,
                       const std::vector<PoseFrame>& truth) {
  std::map<int, Rigid3> by_frame;
  for (const PoseFrame& t : truth) by_frame[t.frame] = t.pose;
  ErrorAccumulator translation, rotation;
  for (const PoseFrame& e : estimate) {
    const auto it = by_frame.find(e.frame);
    if (it == by_frame.end()) continue;
    const Rigid3 diff = e.pose * it->second.inverse();
    const double cos_angle = std::clamp((diff.linear().trace() - 1) / 2, -1.0, 1.0);
    translation.Add(diff.translation().norm());
    rotation.Add(std::acos(cos_angle) * 180 / M_PI);
  }
  PoseError error;
  error.frames = static_cast<int>(translation.count);
  error.translation_rms_mm = translation.Rms();
  error.rotation_rms_deg = rotation.Rms();
  error.translation_max_mm = translation.max;
  error.rotation_max_deg = rotation.max;
  return error;
}

std::string JawError::BriefReport() const {
  return fmt::format(
      "jaw vs truth over {} frames: RMS open {:.4f} deg, lateral {:.4f} deg, protrude {:.4f} "
      "mm (max {:.4f}, {:.4f}, {:.4f})",
      frames, rms[0], rms[1], rms[2], max[0], max[1], max[2]);
}

JawError CompareJaw(const std::vector<JawFrame>& estimate,
                    const std::vector<JawFrame>& truth) {
  std::map<int, JawPose> by_frame;
  for (const JawFrame& t : truth) by_frame[t.frame] = t.pose;
  std::array<ErrorAccumulator, 3> sums;
  for (const JawFrame& e : estimate) {
    const auto it = by_frame.find(e.frame);
    if (it == by_frame.end()) continue;
    const std::array<double, 3> a = e.pose.ToArray(), b = it->second.ToArray();
    for (int i = 0; i < 3; ++i) sums[i].Add(std::abs(a[i] - b[i]));
  }
  JawError error;
  error.frames = static_cast<int>(sums[0].count);
  for (int i = 0; i < 3; ++i) {
    error.rms[i] = sums[i].Rms();
    error.max[i] = sums[i].max;
  }
  return error;
}

}  // namespace hmc
