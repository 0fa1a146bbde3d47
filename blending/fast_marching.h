// Geodesic distances on a triangle mesh by fast marching (Kimmel & Sethian
// 1998, "Computing geodesic paths on manifolds", PNAS 95(15)).
//
// A vertex's distance is updated from each incident triangle whose two other
// corners are already accepted, by the planar wavefront through them (first
// order). Obtuse triangles: Kimmel & Sethian unfold them into acute
// neighbours; we use the simpler fallback of Dijkstra-like edge updates
// (T(a) + |a - v|) whenever the planar wavefront's characteristic does not
// enter the triangle at v, which keeps the scheme causal and monotone at the
// cost of a small overestimate on obtuse triangles only. Error is O(h) on
// meshes without obtuse triangles.
#pragma once

#include <vector>

#include <Eigen/Core>

#include "core/types.h"

namespace hmc {

// One source of a march: vertex `vertex` starts at `distance` (mm) and
// carries `label` (the site it belongs to).
struct MarchSource {
  int vertex = -1;
  double distance = 0.0;
  int label = 0;
};

// Precomputed vertex -> triangle adjacency of one mesh, reused by many marches.
class FastMarching {
 public:
  // V: V x 3 vertex positions (mm); F: F x 3 triangles. Both must outlive
  // this object.
  FastMarching(const MatX3d& V, const MatX3i& F);

  struct Result {
    Eigen::VectorXd distance;  // V: geodesic distance (mm); +inf unreached
    Eigen::VectorXi label;     // V: label of the nearest source; -1 unreached
  };

  // Multi-source march over the whole mesh.
  Result Run(const std::vector<MarchSource>& sources) const;

  // Reusable per-thread state of a restricted march (O(touched) per march).
  struct Scratch {
    std::vector<double> distance;
    std::vector<int> stamp;   // == generation: distance is valid
    std::vector<char> state;  // 0 trial, 1 accepted, 2 rejected
    int generation = 0;
    std::vector<int> accepted;  // accepted vertices in order of acceptance
  };

  // Single-source march from `source` that accepts (and propagates from)
  // only the vertices u whose distance is < bound(u); stops when none is
  // left. On return scratch->accepted lists them and DistanceOf() gives
  // their distances. Used to insert a vertex as a new site into a geodesic
  // Voronoi diagram (bound = distance to the existing sites).
  // bound: V distances (mm).
  void MarchBounded(int source, const Eigen::VectorXd& bound,
                    Scratch* scratch) const;
  static double DistanceOf(const Scratch& scratch, int v) {
    return scratch.distance[v];
  }

  int NumVertices() const { return static_cast<int>(V_.rows()); }
  // Triangles using vertex v: tri_[tri_start_[v] .. tri_start_[v + 1]).
  const std::vector<int>& tri_start() const { return tri_start_; }
  const std::vector<int>& tri() const { return tri_; }

  // The first-order update of vertex v from the accepted corners a and b of
  // one triangle with distances ta and tb (planar wavefront, or the edge
  // fallback when its characteristic does not come through the triangle).
  double TriangleUpdate(int v, int a, double ta, int b, double tb) const;

 private:
  const MatX3d& V_;
  const MatX3i& F_;
  std::vector<int> tri_start_;
  std::vector<int> tri_;
};

}  // namespace hmc
