// Triangle meshes with optional texture coordinates (libigl-style arrays).
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "core/types.h"

namespace hmc {

struct TriMesh {
  MatX3d V;    // V x 3 vertex positions (mm)
  MatX3i F;    // F x 3 vertex indices per triangle, counter-clockwise seen
               // from outside the face
  MatX2d UV;   // T x 2 texture coordinates (empty: no UVs); T >= V at seams
  MatX3i FUV;  // F x 3 indices into UV per triangle corner (empty iff UV is)

  int NumVertices() const { return static_cast<int>(V.rows()); }
  int NumFaces() const { return static_cast<int>(F.rows()); }
  bool HasUVs() const { return UV.rows() > 0; }
};

// A point on a mesh surface: triangle `face` and barycentric weights over its
// three corners (sum 1). Topology only; evaluate it on any vertex positions
// with the same triangles (neutral, a shape, a frame).
struct SurfacePoint {
  int face = -1;
  Vec3 bary = Vec3(1.0 / 3, 1.0 / 3, 1.0 / 3);
};

// x(s) = sum_i bary_i X(F(face, i)).
// X: V x 3 positions; F: F x 3 triangles.
Vec3 EvaluateSurfacePoint(const SurfacePoint& point, const MatX3i& F,
                          const MatX3d& X);

// Throws InputError when site `k` lies on a triangle that `mesh` does not
// have (the sites were made for another mesh).
void CheckSiteOnMesh(const TriMesh& mesh, const SurfacePoint& site, size_t k);

// The closest point to p on triangles [first_face, end_face) of `mesh`
// (end_face < 0: to the last), each tested; the first of equally close.
SurfacePoint ClosestSurfacePoint(const TriMesh& mesh, const Vec3& p, int first_face = 0,
                                 int end_face = -1);

// A surface point exactly at vertex `v` (one-hot barycentrics on one of the
// triangles using it). Requires v to be used by a triangle.
SurfacePoint SurfacePointAtVertex(const MatX3i& F, int v);

// One UV per vertex: the UV of the first triangle corner that uses it. At UV
// seams this picks one side; one chart covering the face is assumed.
// Returns V x 2 (empty if the mesh has no UVs).
MatX2d PerVertexUVs(const TriMesh& mesh);

// Area-weighted vertex normals (unit length; zero for unused vertices).
MatX3d VertexNormals(const MatX3d& V, const MatX3i& F);

// Axis-aligned bounding box of the rows of X: min (row 0) and max (row 1).
Eigen::Matrix<double, 2, 3> BoundingBox(const MatX3d& X);

}  // namespace hmc
