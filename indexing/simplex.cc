#include "indexing/simplex.h"

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
  ClosestPoint out;
  auto finish = [&](double u, double v, double w) {
    out.weights = {u, v, w, 0.0};
    out.point = u * a + v * b + w * c;
    out.distance = (out.point - p).norm();
    return out;
  };
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return finish(1, 0, 0);
  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return finish(0, 1, 0);
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    const double v = d1 / (d1 - d3);
    return finish(1 - v, v, 0);
  }
  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return finish(0, 0, 1);
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    const double w = d2 / (d2 - d6);
    return finish(1 - w, 0, w);
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return finish(0, 1 - w, w);
  }
  const double denom = va + vb + vc;
  if (!(std::abs(denom) > 0)) {
    // Degenerate (collinear) triangle: the nearest of its three edges.
    ClosestPoint best;
    best.distance = std::numeric_limits<double>::infinity();
    const std::array<std::array<int, 2>, 3> edges = {{{0, 1}, {0, 2}, {1, 2}}};
    const std::array<Vec3, 3> x = {a, b, c};
    for (const auto& e : edges) {
      const Vec3 d = x[e[1]] - x[e[0]];
      const double len2 = d.squaredNorm();
      const double t =
          len2 > 0 ? std::clamp((p - x[e[0]]).dot(d) / len2, 0.0, 1.0) : 0.0;
      const Vec3 q = x[e[0]] + t * d;
      const double dist = (q - p).norm();
      if (dist < best.distance) {
        best = ClosestPoint();
        best.point = q;
        best.distance = dist;
        best.weights[e[0]] = 1 - t;
        best.weights[e[1]] = t;
      }
    }
    return best;
  }
  const double v = vb / denom, w = vc / denom;
  return finish(1 - v - w, v, w);
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
  static constexpr std::array<std::array<int, 3>, 4> kFaces = {
      {{0, 1, 2}, {0, 1, 3}, {0, 2, 3}, {1, 2, 3}}};
  out.distance = std::numeric_limits<double>::infinity();
  for (const auto& f : kFaces) {
    const ClosestPoint c = ClosestPointOnTriangle(s.x[f[0]], s.x[f[1]],
                                                  s.x[f[2]], p);
    if (c.distance < out.distance) {
      out.point = c.point;
      out.distance = c.distance;
      out.weights = {0, 0, 0, 0};
      for (int i = 0; i < 3; ++i) out.weights[f[i]] = c.weights[i];
    }
  }
  return out;
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
