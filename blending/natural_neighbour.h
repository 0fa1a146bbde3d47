// Natural-neighbour (Sibson) weights of the mesh vertices over the bundle
// sites, computed once per actor (paper, "Smoothness Considerations";
// Sibson 1980; discrete version: Park et al. 2006).
//
// The sites are the bundles' surface points on the neutral. Their Voronoi
// diagram is built in UV space (default; the paper found it smoother) or on
// the mesh with geodesic distances by fast marching (Kimmel & Sethian 1998).
// Inserting vertex v as a new site, lambda_k(v) is the area its cell steals
// from site k's cell, normalised by the total stolen area. Properties:
// lambda >= 0, sum_k lambda_k(v) = 1, lambda_k(site k) = 1, continuous.
#pragma once

#include <iosfwd>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/SparseCore>

#include "core/mesh.h"
#include "core/options.h"

namespace hmc {

struct NaturalNeighbourOptions {
  std::string domain = "uv";  // "uv" (default) or "geodesic"
  int uv_resolution = 1024;   // pixels per side of the discrete UV raster

  void Register(OptionFields* fields);
  bool Check() const;
};

struct NaturalNeighbourWeights {
  // V x K sparse weights lambda_k(v); each row >= 0 and sums to 1.
  Eigen::SparseMatrix<double, Eigen::RowMajor> weights;
  // K lists: the natural neighbours of each site (sites whose Voronoi cells
  // share an edge with its cell), sorted ascending.
  std::vector<std::vector<int>> site_neighbours;
  // V: the site whose Voronoi cell contains each vertex.
  Eigen::VectorXi cell;

  void Write(std::ostream& out) const;  // binary, for the index cache
  static NaturalNeighbourWeights Read(std::istream& in);
};

// neutral: mesh with UVs (required for domain "uv").
// sites: K bundle surface points on the neutral.
NaturalNeighbourWeights ComputeNaturalNeighbourWeights(
    const TriMesh& neutral, const std::vector<SurfacePoint>& sites,
    const NaturalNeighbourOptions& options);

// Normalises per-vertex stolen areas into weights: row v holds
// area_k / sum_k area_k for the (site k, area_k) pairs of stolen[v]. A vertex
// that steals nothing sits on a site: Sibson's insertion leaves every cell
// unchanged and the vertex adopts the cell of the site it coincides with
// (paper, "Smoothness Considerations"), so its weight is 1 on cell[v].
// Returns V x num_sites.
Eigen::SparseMatrix<double, Eigen::RowMajor> WeightsFromStolenAreas(
    const std::vector<std::vector<std::pair<int, double>>>& stolen,
    const Eigen::VectorXi& cell, int num_sites);

}  // namespace hmc
