#include "core/triangle.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace hmc {

Vec3 ClosestPointBarycentrics(const Vec3& p, const Vec3& a, const Vec3& b,
                              const Vec3& c) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return Vec3(1, 0, 0);
  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return Vec3(0, 1, 0);
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    const double v = d1 / (d1 - d3);
    return Vec3(1 - v, v, 0);
  }
  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return Vec3(0, 0, 1);
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    const double w = d2 / (d2 - d6);
    return Vec3(1 - w, 0, w);
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return Vec3(0, 1 - w, w);
  }
  const double denom = va + vb + vc;
  if (std::abs(denom) > 0) {
    const double v = vb / denom, w = vc / denom;
    return Vec3(1 - v - w, v, w);
  }
  // Degenerate (collinear) triangle: the nearest point of its three edges.
  Vec3 best_weights(1, 0, 0);
  double best = std::numeric_limits<double>::infinity();
  const std::array<std::array<int, 2>, 3> edges = {{{0, 1}, {0, 2}, {1, 2}}};
  const std::array<Vec3, 3> x = {a, b, c};
  for (const auto& e : edges) {
    const Vec3 d = x[e[1]] - x[e[0]];
    const double len2 = d.squaredNorm();
    const double t =
        len2 > 0 ? std::clamp((p - x[e[0]]).dot(d) / len2, 0.0, 1.0) : 0.0;
    const double dist = (x[e[0]] + t * d - p).norm();
    if (dist < best) {
      best = dist;
      best_weights.setZero();
      best_weights[e[0]] = 1 - t;
      best_weights[e[1]] = t;
    }
  }
  return best_weights;
}

}  // namespace hmc
