// One bundle's piece of the local geometric index (paper, "Local Geometric
// Indexing" and "Tetrahedralization"; docs/ARCHITECTURE.md, "Method steps", 2-5): its
// point cloud, the overlapping non-manifold tetrahedra over it, and a uniform
// grid listing the simplices overlapping each cell (Fujimoto et al. 1988,
// "ARTS: accelerated ray-tracing system"; Pharr & Humphreys 2010).
//
// Besides the tetrahedra from all 4-combinations of the points, the index
// keeps the well-shaped triangles and the edges that are not faces of kept
// simplices, and every point, as lower dimensional simplices: flat or tiny
// clouds (a bundle moved by one or two shapes) have no good tetrahedra at
// all, and a dataset point must stay reachable even when every tetrahedron
// through it was pruned.
#pragma once

#include <array>
#include <cstdint>
#include <iosfwd>
#include <vector>

#include "core/types.h"
#include "indexing/index_options.h"
#include "indexing/simplex.h"

namespace hmc {

// A simplex of the cloud: corners index the cloud's points; `size` 1..4.
struct CloudSimplex {
  std::array<uint16_t, 4> corner = {0, 0, 0, 0};
  uint8_t size = 0;
};

// One simplex containing (or nearest to) the query.
struct IndexCandidate {
  int simplex = -1;
  std::array<double, 4> weights = {0, 0, 0, 0};  // convex, over the corners
  Vec3 point = Vec3::Zero();  // the weights' position (== query when inside)
  double distance = 0.0;      // |point - query| (mm)
};

struct IndexQuery {
  bool inside = false;    // some simplex contains the query (within tolerance)
  double distance = 0.0;  // distance to the data (0 when inside; mm)
  std::vector<IndexCandidate> candidates;  // sorted by simplex id; one per
                                           // support (corners of non-zero
                                           // weight): the lowest id
};

struct BundleIndexStats {
  int points = 0;
  int64_t tets_candidate = 0;  // C(points, 4)
  int64_t tets_kept = 0;
  int64_t triangles_kept = 0;
  int64_t edges_kept = 0;
  std::array<int, 3> grid_cells = {0, 0, 0};
  int64_t grid_entries = 0;
  int64_t memory_bytes = 0;
};

class BundleIndex {
 public:
  BundleIndex() = default;

  // points: P x 3 cloud (mm, unskinned head space); P <= 65535.
  // point_shapes: P entries, the shape each point stands for (-1: neutral).
  static BundleIndex Build(const MatX3d& points, std::vector<int> point_shapes,
                           const IndexOptions& options);

  // Every simplex containing p with its convex weights, one per support;
  // the triangles and edges only when no tetrahedron contains p (they stand
  // in where tetrahedra do not reach; the points are always tested, so a
  // dataset point stays exact). When none contains p: the simplices whose
  // closest point is within `outside_slack_mm` of the closest distance to
  // the union of simplices (each with its closest point and weights).
  IndexQuery Query(const Vec3& p, double outside_slack_mm,
                   const IndexOptions& options) const;

  // Same result by testing every simplex (no grid); for tests.
  IndexQuery QueryBruteForce(const Vec3& p, double outside_slack_mm,
                             const IndexOptions& options) const;

  int NumPoints() const { return static_cast<int>(points_.rows()); }
  const MatX3d& points() const { return points_; }
  const std::vector<int>& point_shapes() const { return point_shapes_; }
  const std::vector<CloudSimplex>& simplices() const { return simplices_; }
  const BundleIndexStats& stats() const { return stats_; }
  SimplexCorners Corners(int simplex) const;
  // Whether simplex s holds p (tetrahedra: convex barycentrics within
  // inside_tolerance; lower-dimensional simplices: within on_data_mm); if
  // so, fills *candidate. The one containment test of Query and
  // QueryBruteForce.
  bool Contains(int64_t s, const Vec3& p, const IndexOptions& options,
                IndexCandidate* candidate) const;
  // The 0-simplex of point i (every point has one, the last P simplices).
  int PointSimplex(int i) const {
    return static_cast<int>(simplices_.size()) - NumPoints() + i;
  }

  void Write(std::ostream& out) const;
  static BundleIndex Read(std::istream& in);

 private:
  void BuildGrid(const IndexOptions& options);
  void ComputeBoxes();
  // tet_faces_: the ids of each tetrahedron's faces, in kTetFaces order; a
  // face is an ordered corner triple, so tetrahedra sharing it (with the
  // corners in the same order, as Build's ascending ones do) share its id.
  void ComputeFaces();
  // outer_planes_: planes n . x <= offset, n from a fixed set of directions,
  // that hold every point of the cloud and so every simplex. A query farther
  // out than the containment tolerances from one of them is in no simplex,
  // and Query skips the inside test (a projected bundle's cell lists
  // hundreds of simplices).
  void ComputeOuterPlanes();
  // max over the outer planes of n . p - offset: when positive, a lower
  // bound of p's distance to the cloud's convex hull.
  double OuterPlaneDistance(const Vec3& p) const;
  // The closest point of tetrahedron s to a p outside it: the nearest of its
  // faces, each face's closest point computed once per query (a projection
  // reaches hundreds of tetrahedra around the same faces). Equals
  // ClosestPointOnSimplex for such p.
  ClosestPoint ClosestPointOutsideTet(int64_t s, const Vec3& p) const;
  // The inside candidates among simplices [begin, end) (ascending ids).
  void CollectInside(const uint32_t* begin, const uint32_t* end, const Vec3& p,
                     const IndexOptions& options,
                     std::vector<IndexCandidate>* out) const;
  // Distance from p to simplex s's bounding box: a lower bound of its
  // distance to the simplex, so most simplices of a cell are rejected
  // without their barycentrics.
  double BoxDistance(int64_t s, const Vec3& p) const;
  std::array<int, 3> CellOf(const Vec3& p) const;

  MatX3d points_;
  std::vector<int> point_shapes_;
  std::vector<CloudSimplex> simplices_;  // tets first, then lower dimensions
  std::vector<std::array<float, 6>> boxes_;  // per simplex: min xyz, max xyz
  std::vector<std::array<uint32_t, 4>> tet_faces_;  // per tetrahedron
  uint32_t num_faces_ = 0;
  std::vector<Eigen::Vector4d> outer_planes_;  // n (unit), offset
  double diameter_ = 0.0;  // of the cloud's bounding box (mm)
  int64_t num_tets_ = 0;
  Vec3 grid_origin_ = Vec3::Zero();
  double cell_size_ = 1.0;
  std::array<int, 3> grid_n_ = {1, 1, 1};
  std::vector<uint32_t> cell_start_;  // CSR over cells, x fastest
  std::vector<uint32_t> cell_items_;
  BundleIndexStats stats_;
};

}  // namespace hmc
