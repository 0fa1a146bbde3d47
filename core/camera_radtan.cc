#include "core/camera_radtan.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace hmc {
namespace {

constexpr double kHalfPi = 1.57079632679489661923;

// The largest r^2 searched for the end of the one-to-one range: r = 1000,
// 89.94 degrees off axis (a pinhole image has no point at 90).
constexpr double kMaxR2 = 1e6;

// r * radial(r), the radial part alone. k: k1, k2, p1, p2, k3.
double RadialDistort(const double* k, double r) {
  const double u = r * r;
  return r * (1.0 + u * (k[0] + u * (k[1] + u * k[4])));
}

// d (r radial(r)) / dr.
double RadialSlopeAt(const double* k, double r) {
  const double u = r * r;
  return 1.0 + u * (3.0 * k[0] + u * (5.0 * k[1] + u * 7.0 * k[4]));
}

// The end of the one-to-one range as r^2.
double MaxR2(const double* k) {
  double slope_k[4];
  RadTan::RadialSlope(k, slope_k);
  return std::min(kMaxR2, fisheye_internal::FirstSlopeZeroBelow(slope_k, kMaxR2));
}

// The radius r in [0, r_max] with r radial(r) = r_d, by Newton kept inside a
// bracket (r radial(r) increases on [0, r_max]); r_max if r_d lies beyond.
double InvertRadial(const double* k, double r_d, double r_max) {
  if (RadialDistort(k, r_max) <= r_d) return r_max;
  double lo = 0.0;
  double hi = r_max;
  double r = std::min(r_d, r_max);
  for (int iteration = 0; iteration < 100; ++iteration) {
    const double f = RadialDistort(k, r) - r_d;
    if (f == 0.0) break;
    (f < 0.0 ? lo : hi) = r;
    double next = r - f / RadialSlopeAt(k, r);
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
    const double step = std::abs(next - r);
    r = next;
    if (step <= 1e-16 * std::max(1.0, r)) break;
  }
  return r;
}

// The distorted normalised point of (x, y) and its 2 x 2 Jacobian (row
// major). k: k1, k2, p1, p2, k3.
void Distort(const double* k, double x, double y, double* d, double* jacobian) {
  const double k1 = k[0], k2 = k[1], p1 = k[2], p2 = k[3], k3 = k[4];
  const double r2 = x * x + y * y;
  const double radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
  const double d_radial = k1 + r2 * (2.0 * k2 + r2 * 3.0 * k3);  // d radial / d r^2
  d[0] = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
  d[1] = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
  const double cross = 2.0 * x * y * d_radial + 2.0 * p1 * x + 2.0 * p2 * y;
  jacobian[0] = radial + 2.0 * x * x * d_radial + 2.0 * p1 * y + 6.0 * p2 * x;
  jacobian[1] = cross;
  jacobian[2] = cross;
  jacobian[3] = radial + 2.0 * y * y * d_radial + 6.0 * p1 * y + 2.0 * p2 * x;
}

}  // namespace

void RadTan::RadialSlope(const double* k, double* slope_k) {
  slope_k[0] = k[kRadTanK1];
  slope_k[1] = k[kRadTanK2];
  slope_k[2] = k[kRadTanK3];
  slope_k[3] = 0.0;
}

double RadTan::MaxTheta(const double* k) {
  const double u = MaxR2(k);
  return u >= kMaxR2 ? kHalfPi : std::atan(std::sqrt(u));
}

bool RadTan::Unproject(const double* intrinsics, const double* pixel, double* bearing) {
  const double* k = intrinsics + kK1;
  const double m[2] = {(pixel[0] - intrinsics[kCx]) / intrinsics[kFx],
                       (pixel[1] - intrinsics[kCy]) / intrinsics[kFy]};
  const double r_d = std::hypot(m[0], m[1]);
  if (!std::isfinite(r_d)) return false;
  const double u_max = MaxR2(k);
  const double r_max = std::sqrt(u_max);
  // Start from the radial inverse (exact without tangential terms), then
  // Newton on both coordinates; a step that does not reduce the residual or
  // leaves the one-to-one range is halved.
  double p[2] = {0.0, 0.0};
  if (r_d > 0.0) {
    const double r = InvertRadial(k, r_d, r_max);
    p[0] = m[0] * r / r_d;
    p[1] = m[1] * r / r_d;
  }
  double d[2], jacobian[4];
  Distort(k, p[0], p[1], d, jacobian);
  double residual = std::hypot(d[0] - m[0], d[1] - m[1]);
  const double tolerance = 1e-12 * std::max(1.0, r_d);
  for (int iteration = 0; iteration < 50 && residual > 1e-3 * tolerance; ++iteration) {
    const double det = jacobian[0] * jacobian[3] - jacobian[1] * jacobian[2];
    if (!(std::abs(det) > 0.0)) break;
    const double e[2] = {d[0] - m[0], d[1] - m[1]};
    const double step[2] = {(jacobian[3] * e[0] - jacobian[1] * e[1]) / det,
                            (jacobian[0] * e[1] - jacobian[2] * e[0]) / det};
    bool improved = false;
    for (double scale = 1.0; scale > 1e-6; scale *= 0.5) {
      const double q[2] = {p[0] - scale * step[0], p[1] - scale * step[1]};
      if (!(q[0] * q[0] + q[1] * q[1] <= u_max)) continue;
      double dq[2], jq[4];
      Distort(k, q[0], q[1], dq, jq);
      const double rq = std::hypot(dq[0] - m[0], dq[1] - m[1]);
      if (rq < residual) {
        p[0] = q[0];
        p[1] = q[1];
        d[0] = dq[0];
        d[1] = dq[1];
        std::copy(jq, jq + 4, jacobian);
        residual = rq;
        improved = true;
        break;
      }
    }
    if (!improved) break;
  }
  if (!(residual <= tolerance)) return false;
  double slope_k[4];
  RadialSlope(k, slope_k);
  if (!fisheye_internal::IsSlopePositiveUpTo(slope_k, p[0] * p[0] + p[1] * p[1])) return false;
  const double norm = std::sqrt(p[0] * p[0] + p[1] * p[1] + 1.0);
  bearing[0] = p[0] / norm;
  bearing[1] = p[1] / norm;
  bearing[2] = 1.0 / norm;
  return true;
}

}  // namespace hmc
