// Small exact geometry on one triangle, shared by the actor loader (markers
// on polygons) and the index (closest point on the union of tetrahedra).
#pragma once

#include "core/types.h"

namespace hmc {

// Barycentric weights (over a, b, c; >= 0, sum 1) of the point of triangle
// (a, b, c) closest to p (Ericson, "Real-Time Collision Detection", 2005,
// section 5.1.5). A degenerate (collinear) triangle gives the closest point
// of its nearest edge.
Vec3 ClosestPointBarycentrics(const Vec3& p, const Vec3& a, const Vec3& b,
                              const Vec3& c);

}  // namespace hmc
