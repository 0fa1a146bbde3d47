// The double-sphere camera (Usenko, Demmel & Cremers, "The Double Sphere
// Camera Model", 3DV 2018; basalt's camera/double_sphere_camera.hpp), a
// closed-form model of wide and fisheye lenses beyond 180 degrees:
//
//   d1    = |(x, y, z)|,        w = xi d1 + z
//   d2    = |(x, y, w)|
//   den   = alpha d2 + (1 - alpha) w
//   pixel = (fx x / den + cx,  fy y / den + cy)
//
// with xi the offset between the two unit spheres and alpha in [0, 1].
// Domain (where the model is one-to-one): z > -w2 d1 with
//   w1 = alpha / (1 - alpha) if alpha <= 0.5, else (1 - alpha) / alpha
//   w2 = (w1 + xi) / sqrt(2 w1 xi + xi^2 + 1).
// Unproject is the paper's closed-form inverse, accepted only where its
// square roots are real and the ray lies in that domain.
#pragma once

#include <cmath>

#include "core/camera_fisheye.h"

namespace hmc {

struct DoubleSphere {
  // Distortion parameters from kK1 in this order.
  enum { kXi = 0, kAlpha, kNumDoubleSphere };

  // Projects `point_in_cam` (3) to `pixel` (2); false (pixel untouched)
  // outside the domain. `intrinsics`: fx, fy, cx, cy, xi, alpha. T may be a
  // ceres::Jet.
  template <typename T>
  static bool Project(const T* intrinsics, const T* point_in_cam, T* pixel);

  // A unit bearing vector for `pixel`; false outside the model's image.
  static bool Unproject(const double* intrinsics, const double* pixel, double* bearing);

  // The domain's bound on cos(angle off axis): z / d1 > -w2. k: xi, alpha.
  static double MinCosTheta(const double* k);

  // The largest angle off axis (rad) of the domain. k: xi, alpha.
  static double MaxTheta(const double* k);
};

template <typename T>
bool DoubleSphere::Project(const T* intrinsics, const T* point_in_cam, T* pixel) {
  using std::sqrt;
  const T& x = point_in_cam[0];
  const T& y = point_in_cam[1];
  const T& z = point_in_cam[2];
  const T& xi = intrinsics[kK1 + kXi];
  const T& alpha = intrinsics[kK1 + kAlpha];
  const double xs = fisheye_internal::ScalarPart(x);
  const double ys = fisheye_internal::ScalarPart(y);
  const double zs = fisheye_internal::ScalarPart(z);
  const double d1s = std::sqrt(xs * xs + ys * ys + zs * zs);
  if (!(d1s > 0) || !std::isfinite(d1s)) return false;
  const double ks[2] = {fisheye_internal::ScalarPart(xi), fisheye_internal::ScalarPart(alpha)};
  if (!(zs > MinCosTheta(ks) * d1s)) return false;
  const T d1 = sqrt(x * x + y * y + z * z);
  const T w = xi * d1 + z;
  const T d2_squared = x * x + y * y + w * w;
  if (!(fisheye_internal::ScalarPart(d2_squared) > 0)) return false;
  const T den = alpha * sqrt(d2_squared) + (T(1.0) - alpha) * w;
  if (!(fisheye_internal::ScalarPart(den) > 0)) return false;
  pixel[0] = intrinsics[kFx] * x / den + intrinsics[kCx];
  pixel[1] = intrinsics[kFy] * y / den + intrinsics[kCy];
  return true;
}

}  // namespace hmc
