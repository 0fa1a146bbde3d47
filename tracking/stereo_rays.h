// Rays of the calibrated stereo rig in helmet space, for the epipolar
// consistency of a pair of detections (docs/tracking.md).
//
// A pixel u of camera c has the ray o_c + s d_c(u), s > 0, with o_c the
// camera centre in helmet space and d_c(u) = R_c^T b(u), b the Kannala-Brandt
// bearing (core/camera_fisheye.h, exact beyond 90 degrees). Two rays' closest
// approach: with w = o_0 - o_1, a = d0.d0, b = d0.d1, c = d1.d1, d = d0.w,
// e = d1.w, s0 = (b e - c d) / (a c - b^2), s1 = (a e - b d) / (a c - b^2);
// gap = |o_0 + s0 d0 - o_1 - s1 d1| (mm) and the midpoint triangulates.
#pragma once

#include <vector>

#include "core/calibration.h"
#include "core/types.h"

namespace hmc {

struct Ray3 {
  bool ok = false;
  Vec3 origin = Vec3::Zero();     // camera centre (helmet space, mm)
  Vec3 direction = Vec3::Zero();  // unit (helmet space)
};

Ray3 PixelRay(const HelmetCamera& camera, const Vec2& pixel);

struct RayApproach {
  bool ok = false;     // both distances positive and the rays not parallel
  double gap = 0;      // closest distance between the rays (mm)
  Vec3 midpoint = Vec3::Zero();
  double s0 = 0, s1 = 0;  // distances along each ray (mm)
};

RayApproach ClosestApproach(const Ray3& a, const Ray3& b);

}  // namespace hmc
