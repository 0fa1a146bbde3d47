#include "core/camera_fisheye.h"

#include <algorithm>
#include <cmath>
#include <limits>


namespace hmc {
namespace {

constexpr double kPi = 3.14159265358979323846;

// d theta_d / d theta as a polynomial in u = theta^2.
double Slope(const double* k, double u) {
  return 1.0 + u * (3.0 * k[0] + u * (5.0 * k[1] + u * (7.0 * k[2] +
                                                         u * 9.0 * k[3])));
}

// theta_d(theta).
double Distort(const double* k, double theta) {
  const double u = theta * theta;
  return theta * (1.0 + u * (k[0] + u * (k[1] + u * (k[2] + u * k[3]))));
}

// A rigorous sufficient condition for Slope > 0 on [0, theta^2]: even with
// every negative term at its largest magnitude the slope stays positive.
// Holds for most real lenses over most of their field, so the adaptive
// search below is rarely needed.
bool CertainlyMonotonicSquared(const double* k, double u_max) {
  const double c[4] = {3.0 * k[0], 5.0 * k[1], 7.0 * k[2], 9.0 * k[3]};
  double lower = 1.0;
  double power = 1.0;
  for (double ci : c) {
    power *= u_max;
    lower += std::min(0.0, ci) * power;
  }
  return lower > 0.0;
}

bool CertainlyMonotonic(const double* k, double theta) {
  return CertainlyMonotonicSquared(k, theta * theta);
}

constexpr double kNoZero = std::numeric_limits<double>::infinity();

// The smallest u in [a, b] where the slope (a polynomial in u = theta^2)
// reaches zero, or kNoZero; `slope_a` = Slope(k, a). Adaptive bisection
// with a Lipschitz bound: |d slope / du| <= L on [a, b], so slope_a > L (b - a)
// proves the slope positive on the whole interval. Intervals that cannot be
// proved positive are split, left first; one still unproved at width
// (b - a) / 2^50 holds a zero to double precision. Rigorous (no sampling
// gaps) and cheap: a few dozen evaluations unless the slope nearly vanishes.
double FirstSlopeZero(const double* k, double a, double b, double slope_a,
                      int depth) {
  if (slope_a <= 0.0) return a;
  const double lipschitz = std::abs(3.0 * k[0]) +
                           2.0 * std::abs(5.0 * k[1]) * b +
                           3.0 * std::abs(7.0 * k[2]) * b * b +
                           4.0 * std::abs(9.0 * k[3]) * b * b * b;
  if (slope_a > lipschitz * (b - a)) return kNoZero;
  if (depth >= 50) return a;
  const double mid = 0.5 * (a + b);
  const double left = FirstSlopeZero(k, a, mid, slope_a, depth + 1);
  if (left != kNoZero) return left;
  return FirstSlopeZero(k, mid, b, Slope(k, mid), depth + 1);
}

// First zero of the slope in (0, pi], or pi.
double MonotonicLimit(const double* k) {
  if (CertainlyMonotonic(k, kPi)) return kPi;
  const double u = FirstSlopeZero(k, 0.0, kPi * kPi, 1.0, 0);
  return u == kNoZero ? kPi : std::sqrt(u);
}

}  // namespace

namespace fisheye_internal {

bool IsMonotonicUpTo(const double* k, double theta_rad) {
  if (!(theta_rad >= 0.0) || theta_rad > kPi) return false;
  if (CertainlyMonotonic(k, theta_rad)) return true;
  return FirstSlopeZero(k, 0.0, theta_rad * theta_rad, 1.0, 0) == kNoZero;
}

double FirstSlopeZeroBelow(const double* k, double u_max) {
  if (!(u_max >= 0.0)) return 0.0;
  if (CertainlyMonotonicSquared(k, u_max)) return kNoZero;
  return FirstSlopeZero(k, 0.0, u_max, 1.0, 0);
}

bool IsSlopePositiveUpTo(const double* k, double u_max) {
  return FirstSlopeZeroBelow(k, u_max) == kNoZero;
}

}  // namespace fisheye_internal

bool KannalaBrandt::Unproject(const double* intrinsics, const double* pixel, double* bearing) {
  const double* k = intrinsics + kK1;
  const double mx = (pixel[0] - intrinsics[kCx]) / intrinsics[kFx];
  const double my = (pixel[1] - intrinsics[kCy]) / intrinsics[kFy];
  const double theta_d = std::hypot(mx, my);
  if (!std::isfinite(theta_d)) return false;
  if (theta_d == 0.0) {
    bearing[0] = 0.0;
    bearing[1] = 0.0;
    bearing[2] = 1.0;
    return true;
  }
  const double tolerance = 1e-12 * std::max(1.0, theta_d);
  // Fast path: plain Newton from theta = theta_d*. A converged root is the
  // answer if theta_d(theta) increases on all of [0, root] (f(0) < 0, so it
  // is then the only root in the one-to-one range).
  double theta = theta_d;
  bool converged = false;
  for (int iteration = 0; iteration < 20; ++iteration) {
    const double slope = Slope(k, theta * theta);
    if (!(slope > 0.0)) break;
    const double step = (Distort(k, theta) - theta_d) / slope;
    theta -= step;
    if (!(theta >= 0.0 && theta <= kPi)) break;
    if (std::abs(step) <= 1e-15 * std::max(1.0, theta)) {
      converged = std::abs(Distort(k, theta) - theta_d) <= tolerance &&
                  fisheye_internal::IsMonotonicUpTo(k, theta);
      break;
    }
  }
  if (!converged) {
    // Safe path: Newton kept inside a bracket [lo, hi] with
    // f(lo) < 0 <= f(hi) on the monotonic range; a step leaving it is
    // replaced by bisection, so the iteration cannot escape the range.
    const double theta_max = MonotonicLimit(k);
    // theta_d(theta) increases on [0, theta_max]; beyond theta_d(theta_max)
    // there is no angle in the one-to-one range.
    if (Distort(k, theta_max) < theta_d) return false;
    double lo = 0.0;
    double hi = theta_max;
    theta = std::min(theta_d, theta_max);
    for (int iteration = 0; iteration < 100; ++iteration) {
      const double f = Distort(k, theta) - theta_d;
      if (f == 0.0) {
        converged = true;
        break;
      }
      (f < 0.0 ? lo : hi) = theta;
      const double slope = Slope(k, theta * theta);
      double next = theta - f / slope;
      if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
      const double step = std::abs(next - theta);
      theta = next;
      if (step <= 1e-15 * std::max(1.0, theta) || hi - lo <= 1e-15) {
        converged = true;
        break;
      }
    }
    if (!converged || std::abs(Distort(k, theta) - theta_d) > tolerance) {
      return false;
    }
  }
  const double s = std::sin(theta) / theta_d;
  bearing[0] = s * mx;
  bearing[1] = s * my;
  bearing[2] = std::cos(theta);
  return true;
}

double KannalaBrandt::MaxTheta(const double* k) { return MonotonicLimit(k); }

}  // namespace hmc
