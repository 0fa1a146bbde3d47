// Small exact geometry on one triangle, shared by the actor loader (markers
// on polygons), the index (closest point on the union of tetrahedra) and the
// footage renderer (rays against the face's triangles).
#pragma once

#include <cmath>

#include "core/types.h"

namespace hmc {

// Barycentric weights (over a, b, c; >= 0, sum 1) of the point of triangle
// (a, b, c) closest to p (Ericson, "Real-Time Collision Detection", 2005,
// section 5.1.5). A degenerate (collinear) triangle gives the closest point
// of its nearest edge.
Vec3 ClosestPointBarycentrics(const Vec3& p, const Vec3& a, const Vec3& b,
                              const Vec3& c);

// Ray (origin 0, direction d) against the plane of triangle (p0, p1, p2)
// (Moller & Trumbore 1997, without the inside test): distance along d and
// barycentrics. Returns false if the ray is parallel to the plane. Inline:
// the renderer calls it per pixel.
inline bool IntersectPlane(const Vec3& d, const Vec3& p0, const Vec3& p1, const Vec3& p2,
                           double* dist, Vec3* bary) {
  const Vec3 e1 = p1 - p0;
  const Vec3 e2 = p2 - p0;
  const Vec3 pvec = d.cross(e2);
  const double det = e1.dot(pvec);
  if (std::abs(det) < 1e-300) return false;
  const double inv = 1.0 / det;
  const Vec3 tvec = -p0;
  const double u = tvec.dot(pvec) * inv;
  const Vec3 qvec = tvec.cross(e1);
  const double v = d.dot(qvec) * inv;
  *dist = e2.dot(qvec) * inv;
  *bary = Vec3(1 - u - v, u, v);
  return true;
}

}  // namespace hmc
