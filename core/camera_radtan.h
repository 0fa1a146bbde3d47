// OpenCV's pinhole camera with radial-tangential distortion (the model of
// cv::projectPoints with distCoeffs k1, k2, p1, p2[, k3]; Brown-Conrady),
// the model of narrow helmet lenses:
//
//   (x', y') = (x / z, y / z),  r^2 = x'^2 + y'^2
//   radial   = 1 + k1 r^2 + k2 r^4 + k3 r^6
//   x''      = x' radial + 2 p1 x' y' + p2 (r^2 + 2 x'^2)
//   y''      = y' radial + p1 (r^2 + 2 y'^2) + 2 p2 x' y'
//   pixel    = (fx x'' + cx,  fy y'' + cy)
//
// No skew, no thin-prism or tilt terms. Pixels follow OpenCV
// (core/types.h).
//
// Domain: points in front of the camera (z > 0) whose radius r lies where
// the radial part r * radial(r) is strictly increasing (its slope
// 1 + 3 k1 r^2 + 5 k2 r^4 + 7 k3 r^6 stays positive from the axis), so the
// model is one-to-one there (the small tangential terms of a real lens do
// not change that) and Unproject inverts it. The unprojection is our own
// (Newton on the two image coordinates), not cv::undistortPoints, whose
// fixed-count iteration stops short on strong distortion.
#pragma once

#include <cmath>

#include "core/camera_fisheye.h"

namespace hmc {

struct RadTan {
  // Distortion parameters from kK1 in this order.
  enum { kRadTanK1 = 0, kRadTanK2, kRadTanP1, kRadTanP2, kRadTanK3, kNumRadTan };

  // Projects `point_in_cam` (3) to `pixel` (2); false (pixel untouched)
  // outside the domain above. `intrinsics`: fx, fy, cx, cy, k1, k2, p1, p2,
  // k3. T may be a ceres::Jet.
  template <typename T>
  static bool Project(const T* intrinsics, const T* point_in_cam, T* pixel);

  // A unit bearing vector for `pixel`; false if no point of the domain
  // projects there (to 1e-12 of the normalised coordinates).
  static bool Unproject(const double* intrinsics, const double* pixel, double* bearing);

  // The largest angle off axis (rad) of the domain (radial part only): the
  // first zero of the radial slope, or pi / 2. k: k1, k2, p1, p2, k3.
  static double MaxTheta(const double* k);

  // The radial slope's coefficients in the form of the Kannala-Brandt
  // helpers (k1, k2, k3, 0). k: k1, k2, p1, p2, k3.
  static void RadialSlope(const double* k, double* slope_k);
};

template <typename T>
bool RadTan::Project(const T* intrinsics, const T* point_in_cam, T* pixel) {
  const double zs = fisheye_internal::ScalarPart(point_in_cam[2]);
  if (!(zs > 0) || !std::isfinite(zs)) return false;
  const T xp = point_in_cam[0] / point_in_cam[2];
  const T yp = point_in_cam[1] / point_in_cam[2];
  const T r2 = xp * xp + yp * yp;
  const double r2s = fisheye_internal::ScalarPart(r2);
  if (!std::isfinite(r2s)) return false;
  const T* k = intrinsics + kK1;
  const double ks[5] = {fisheye_internal::ScalarPart(k[kRadTanK1]),
                        fisheye_internal::ScalarPart(k[kRadTanK2]),
                        fisheye_internal::ScalarPart(k[kRadTanP1]),
                        fisheye_internal::ScalarPart(k[kRadTanP2]),
                        fisheye_internal::ScalarPart(k[kRadTanK3])};
  double slope_k[4];
  RadialSlope(ks, slope_k);
  if (!fisheye_internal::IsSlopePositiveUpTo(slope_k, r2s)) return false;
  const T radial = T(1.0) + r2 * (k[kRadTanK1] + r2 * (k[kRadTanK2] + r2 * k[kRadTanK3]));
  const T xy = xp * yp;
  const T xd = xp * radial + T(2.0) * k[kRadTanP1] * xy + k[kRadTanP2] * (r2 + T(2.0) * xp * xp);
  const T yd = yp * radial + k[kRadTanP1] * (r2 + T(2.0) * yp * yp) + T(2.0) * k[kRadTanP2] * xy;
  pixel[0] = intrinsics[kFx] * xd + intrinsics[kCx];
  pixel[1] = intrinsics[kFy] * yd + intrinsics[kCy];
  return true;
}

}  // namespace hmc
