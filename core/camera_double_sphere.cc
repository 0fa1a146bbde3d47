#include "core/camera_double_sphere.h"

#include <algorithm>
#include <cmath>

namespace hmc {

double DoubleSphere::MinCosTheta(const double* k) {
  const double xi = k[kXi];
  const double alpha = k[kAlpha];
  const double w1 = alpha <= 0.5 ? alpha / (1.0 - alpha) : (1.0 - alpha) / alpha;
  const double w2 = (w1 + xi) / std::sqrt(2.0 * w1 * xi + xi * xi + 1.0);
  return -w2;
}

double DoubleSphere::MaxTheta(const double* k) {
  return std::acos(std::clamp(MinCosTheta(k), -1.0, 1.0));
}

bool DoubleSphere::Unproject(const double* intrinsics, const double* pixel, double* bearing) {
  const double xi = intrinsics[kK1 + kXi];
  const double alpha = intrinsics[kK1 + kAlpha];
  const double mx = (pixel[0] - intrinsics[kCx]) / intrinsics[kFx];
  const double my = (pixel[1] - intrinsics[kCy]) / intrinsics[kFy];
  const double r2 = mx * mx + my * my;
  if (!std::isfinite(r2)) return false;
  // Beyond r^2 = 1 / (2 alpha - 1) (alpha > 1/2) no ray images.
  const double inner = 1.0 - (2.0 * alpha - 1.0) * r2;
  if (!(inner >= 0.0)) return false;
  const double mz = (1.0 - alpha * alpha * r2) / (alpha * std::sqrt(inner) + 1.0 - alpha);
  const double mz2 = mz * mz;
  const double disc = mz2 + (1.0 - xi * xi) * r2;
  if (!(disc >= 0.0) || !(mz2 + r2 > 0.0)) return false;
  const double scale = (mz * xi + std::sqrt(disc)) / (mz2 + r2);
  double b[3] = {scale * mx, scale * my, scale * mz - xi};
  const double norm = std::sqrt(b[0] * b[0] + b[1] * b[1] + b[2] * b[2]);
  if (!(norm > 0.0) || !std::isfinite(norm)) return false;
  for (double& v : b) v /= norm;
  // A pixel outside the image of the domain gives a ray the model does not
  // project back there.
  if (!(b[2] > MinCosTheta(intrinsics + kK1))) return false;
  std::copy(b, b + 3, bearing);
  return true;
}

}  // namespace hmc
