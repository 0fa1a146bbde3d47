#include "indexing/simplex.h"

#include "core/triangle.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace hmc {

bool TetBarycentric(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d,
                    const Vec3& p, std::array<double, 4>* weights) {
  Mat3 m;
  m.col(0) = b - a;
  m.col(1) = c - a;
  m.col(2) = d - a;
  const double det = m.determinant();
  if (det == 0.0 || !std::isfinite(det)) return false;
  // Cramer's rule keeps the result independent of pivoting order, so a point
  // shared by two tetrahedra gets the same weights in both.
  const Vec3 r = p - a;
  Mat3 m1 = m, m2 = m, m3 = m;
  m1.col(0) = r;
  m2.col(1) = r;
  m3.col(2) = r;
  const double w1 = m1.determinant() / det;
  const double w2 = m2.determinant() / det;
  const double w3 = m3.determinant() / det;
  (*weights)[0] = 1.0 - w1 - w2 - w3;
  (*weights)[1] = w1;
  (*weights)[2] = w2;
  (*weights)[3] = w3;
  return true;
}

ClosestPoint ClosestPointOnTriangle(const Vec3& a, const Vec3& b,
                                    const Vec3& c, const Vec3& p) {
  const Vec3 w = ClosestPointBarycentrics(p, a, b, c);
  ClosestPoint out;
  out.weights = {w[0], w[1], w[2], 0.0};
  out.point = w[0] * a + w[1] * b + w[2] * c;
  out.distance = (out.point - p).norm();
  return out;
}

ClosestPoint ClosestPointOnSimplex(const SimplexCorners& s, const Vec3& p,
                                   double tolerance) {
  ClosestPoint out;
  switch (s.size) {
    case 1:
      out.point = s.x[0];
      out.weights = {1, 0, 0, 0};
      out.distance = (p - s.x[0]).norm();
      return out;
    case 2: {
      const Vec3 d = s.x[1] - s.x[0];
      const double len2 = d.squaredNorm();
      const double t =
          len2 > 0 ? std::clamp((p - s.x[0]).dot(d) / len2, 0.0, 1.0) : 0.0;
      out.weights = {1 - t, t, 0, 0};
      out.point = (1 - t) * s.x[0] + t * s.x[1];
      out.distance = (out.point - p).norm();
      return out;
    }
    case 3:
      return ClosestPointOnTriangle(s.x[0], s.x[1], s.x[2], p);
    default:
      break;
  }
  std::array<double, 4> w;
  if (TetBarycentric(s.x[0], s.x[1], s.x[2], s.x[3], p, &w) &&
      *std::min_element(w.begin(), w.end()) >= -tolerance) {
    double sum = 0;
    for (double& wi : w) {
      wi = std::max(wi, 0.0);
      sum += wi;
    }
    for (double& wi : w) wi /= sum;
    out.weights = w;
    out.point = p;
    out.distance = 0.0;
    return out;
  }
  return NearestTetFace([&](int f) {
    return ClosestPointOnTriangle(s.x[kTetFaces[f][0]], s.x[kTetFaces[f][1]],
                                  s.x[kTetFaces[f][2]], p);
  });
}

double TetQuality(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  const double longest2 = std::max(
      {(b - a).squaredNorm(), (c - a).squaredNorm(), (d - a).squaredNorm(),
       (c - b).squaredNorm(), (d - b).squaredNorm(), (d - c).squaredNorm()});
  if (longest2 <= 0) return 0.0;
  const double volume = std::abs((b - a).dot((c - a).cross(d - a))) / 6.0;
  return 6.0 * std::sqrt(2.0) * volume / (longest2 * std::sqrt(longest2));
}

double TriangleQuality(const Vec3& a, const Vec3& b, const Vec3& c) {
  const double longest2 = std::max(
      {(b - a).squaredNorm(), (c - a).squaredNorm(), (c - b).squaredNorm()});
  if (longest2 <= 0) return 0.0;
  const double area = 0.5 * (b - a).cross(c - a).norm();
  return 4.0 * area / (std::sqrt(3.0) * longest2);
}

}  // namespace hmc
