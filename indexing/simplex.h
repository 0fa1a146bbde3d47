// Geometry of the simplices of a point cloud (paper, "Local Geometric
// Indexing"): barycentric coordinates in a tetrahedron, closest points on
// points, segments, triangles and tetrahedra, and shape-quality measures used
// to prune tetrahedra.
#pragma once

#include <array>
#include <limits>

#include "core/types.h"

namespace hmc {

// Up to four corner positions; `size` 1 (point), 2 (segment), 3 (triangle)
// or 4 (tetrahedron).
struct SimplexCorners {
  std::array<Vec3, 4> x;
  int size = 4;
};

// The closest point of a simplex to a query point and its convex barycentric
// weights over the simplex's corners (entries >= size are 0).
struct ClosestPoint {
  Vec3 point = Vec3::Zero();
  std::array<double, 4> weights = {0, 0, 0, 0};
  double distance = 0.0;  // |point - query| (mm)
};

// A tetrahedron's faces, as corner indices.
inline constexpr std::array<std::array<int, 3>, 4> kTetFaces = {
    {{0, 1, 2}, {0, 1, 3}, {0, 2, 3}, {1, 2, 3}}};

// The closest point of a tetrahedron to a p outside it: the nearest of its
// faces (the first of equals, in kTetFaces order), with the face's weights
// moved to the tetrahedron's corners. face(f) gives face f's closest point
// (ClosestPointOnTriangle of its corners in kTetFaces order), so that a
// caller can reuse faces shared by several tetrahedra.
template <class FaceClosestPoint>
ClosestPoint NearestTetFace(FaceClosestPoint&& face) {
  ClosestPoint out;
  out.distance = std::numeric_limits<double>::infinity();
  for (int f = 0; f < 4; ++f) {
    const ClosestPoint& c = face(f);
    if (c.distance < out.distance) {
      out.point = c.point;
      out.distance = c.distance;
      out.weights = {0, 0, 0, 0};
      for (int i = 0; i < 3; ++i) out.weights[kTetFaces[f][i]] = c.weights[i];
    }
  }
  return out;
}

// Barycentric coordinates of p in tetrahedron (a, b, c, d), unclamped.
// Returns false for a degenerate tetrahedron (volume 0).
bool TetBarycentric(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d,
                    const Vec3& p, std::array<double, 4>* weights);

// Closest point on a triangle (Ericson, "Real-Time Collision Detection",
// 2005, section 5.1.5: Voronoi regions of the triangle's features).
ClosestPoint ClosestPointOnTriangle(const Vec3& a, const Vec3& b,
                                    const Vec3& c, const Vec3& p);

// Closest point on any simplex. A tetrahedron contains p when all its
// barycentrics are >= -`tolerance`; they are then clamped to >= 0 and
// renormalised (robust at faces, edges and corners) and the distance is 0.
// Otherwise the closest point is the nearest of its four faces.
ClosestPoint ClosestPointOnSimplex(const SimplexCorners& s, const Vec3& p,
                                   double tolerance);

// Tetrahedron quality: 6 sqrt(2) volume / (longest edge)^3, which is 1 for
// the regular tetrahedron and 0 for a flat one (scale invariant).
double TetQuality(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d);

// Triangle quality: 4 area / (sqrt(3) (longest edge)^2), 1 for equilateral.
double TriangleQuality(const Vec3& a, const Vec3& b, const Vec3& c);

}  // namespace hmc
