// The Kannala-Brandt fisheye camera, as in OpenCV's cv::fisheye (k1..k4):
//
//   theta   = atan2(r, z),  r = sqrt(x^2 + y^2)      (angle off the axis)
//   theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8)
//   pixel   = (fx theta_d / r * x + cx,  fy theta_d / r * y + cy)
//
// Kannala & Brandt, "A generic camera model and calibration method for
// conventional, wide-angle, and fish-eye lenses", PAMI 2006 (the 4-parameter
// radially symmetric form). No skew. Pixels follow OpenCV (core/types.h).
//
// Unlike cv::fisheye, points more than 90 degrees off axis (z <= 0) project,
// up to the end of the range where theta_d(theta) is strictly increasing
// (capped at pi); there the model is one-to-one and Unproject inverts it.
// The unprojection is our own: cv::fisheye::undistortPoints returns wrong
// rays beyond ~90 degrees off axis.
#pragma once

#include <cmath>

namespace hmc {

// Layout of the intrinsics array for the templated functions (every model
// shares fx..cy; its distortion parameters follow from kK1: core/camera.h).
enum FisheyeParam { kFx = 0, kFy, kCx, kCy, kK1, kK2, kK3, kK4, kNumFisheyeParams };

namespace fisheye_internal {

// The value part of a scalar: the number itself, or the `.a` of a
// ceres::Jet (duck-typed so this header does not need Ceres). Used only for
// branch decisions, which are not differentiated.
inline double ScalarPart(double x) { return x; }
inline double ScalarPart(float x) { return x; }
template <typename T>
double ScalarPart(const T& jet) {
  return ScalarPart(jet.a);
}

// True if theta_d(theta) is strictly increasing on [0, theta_rad]
// (theta_rad <= pi), i.e. 1 + 3 k1 t^2 + 5 k2 t^4 + 7 k3 t^6 + 9 k4 t^8 > 0.
// k: k1..k4.
bool IsMonotonicUpTo(const double* k, double theta_rad);

// The same for a polynomial in u = r^2 with no cap on the range: true if
// 1 + 3 k1 u + 5 k2 u^2 + 7 k3 u^3 + 9 k4 u^4 > 0 on [0, u_max]. The radial
// part of the pinhole radial-tangential model (core/camera_radtan.h) has
// this slope with k4 = 0.
bool IsSlopePositiveUpTo(const double* k, double u_max);

// The first zero of that slope in [0, u_max], or +infinity.
double FirstSlopeZeroBelow(const double* k, double u_max);

}  // namespace fisheye_internal

// The Kannala-Brandt model's maths on a parameter array (FisheyeParam
// order); the camera that holds a model and its parameters is Camera
// (core/camera.h), which dispatches here.
struct KannalaBrandt {
  // Projects `point_in_cam` (3, camera frame: +z along the optical axis, +x
  // right, +y down) to `pixel` (2). Returns false (pixel untouched) if the
  // point is at the centre, straight behind, or beyond the monotonic range
  // of the polynomial. Not limited to the image: see Camera::IsInImage.
  // `intrinsics`: kNumFisheyeParams values in FisheyeParam order. T may be a
  // ceres::Jet: derivatives are exact, also on the optical axis.
  template <typename T>
  static bool Project(const T* intrinsics, const T* point_in_cam, T* pixel);

  // Inverts Project: a unit bearing vector in the camera frame for `pixel`.
  // Solves theta_d(theta) = theta_d* by Newton; a root is accepted only if
  // the polynomial is monotonic up to it, else the solve is redone by Newton
  // kept inside a bracket of the monotonic range. Returns false when
  // theta_d* lies outside that range (no unique angle) or the iteration does
  // not converge.
  static bool Unproject(const double* intrinsics, const double* pixel, double* bearing);

  // The largest angle off axis (rad) up to which the model is one-to-one:
  // the first zero of d theta_d / d theta, or pi. k: k1..k4.
  static double MaxTheta(const double* k);
};

template <typename T>
bool KannalaBrandt::Project(const T* intrinsics, const T* point_in_cam, T* pixel) {
  using std::atan2;
  using std::sqrt;
  const T& x = point_in_cam[0];
  const T& y = point_in_cam[1];
  const T& z = point_in_cam[2];
  const double xs = fisheye_internal::ScalarPart(x);
  const double ys = fisheye_internal::ScalarPart(y);
  const double zs = fisheye_internal::ScalarPart(z);
  const double rs = std::sqrt(xs * xs + ys * ys);
  if (!(std::isfinite(rs) && std::isfinite(zs))) return false;

  T scale;  // theta_d / r
  // Near the axis, theta = atan(r / z) = r / z - r^3 / (3 z^3) + ..., so
  // theta_d / r -> 1 / z; the dropped terms are below double precision and
  // their derivatives vanish on the axis. This avoids sqrt(0) in Jets.
  if (rs <= 1e-8 * zs) {
    if (zs <= 0) return false;
    scale = T(1.0) / z;
  } else {
    if (rs == 0) return false;  // straight behind (or the origin)
    const T r = sqrt(x * x + y * y);
    const T theta = atan2(r, z);
    const double k_scalar[4] = {
        fisheye_internal::ScalarPart(intrinsics[kK1]),
        fisheye_internal::ScalarPart(intrinsics[kK2]),
        fisheye_internal::ScalarPart(intrinsics[kK3]),
        fisheye_internal::ScalarPart(intrinsics[kK4])};
    if (!fisheye_internal::IsMonotonicUpTo(k_scalar, std::atan2(rs, zs))) {
      return false;
    }
    const T theta2 = theta * theta;
    const T poly =
        T(1.0) +
        theta2 * (intrinsics[kK1] +
                  theta2 * (intrinsics[kK2] +
                            theta2 * (intrinsics[kK3] +
                                      theta2 * intrinsics[kK4])));
    scale = theta * poly / r;
  }
  pixel[0] = intrinsics[kFx] * scale * x + intrinsics[kCx];
  pixel[1] = intrinsics[kFy] * scale * y + intrinsics[kCy];
  return true;
}

}  // namespace hmc
