// The geodesic Voronoi diagram of the bundle sites on the neutral mesh
// (distances by fast marching, Kimmel & Sethian 1998) and the mesh analogue
// of discrete natural-neighbour coordinates (Sibson 1980; Park et al. 2006):
// each vertex is inserted as a new site by a local march restricted to the
// vertices it is closer to than their current site; the stolen area is the
// sum of those vertices' areas (one third of the incident triangle areas).
#pragma once

#include <vector>

#include <Eigen/Core>

#include "blending/fast_marching.h"
#include "blending/natural_neighbour.h"
#include "core/mesh.h"

namespace hmc {

struct GeodesicVoronoi {
  Eigen::VectorXd distance;  // V: geodesic distance to the nearest site (mm)
  Eigen::VectorXi cell;      // V: that site; -1 if no site is reachable
};

// A site inside a triangle starts the march at the triangle's corners with
// their exact (Euclidean, within the triangle) distances.
GeodesicVoronoi ComputeGeodesicVoronoi(const FastMarching& marching,
                                       const TriMesh& mesh,
                                       const std::vector<SurfacePoint>& sites);

// V: one third of the areas of the triangles using each vertex (mm^2).
Eigen::VectorXd VertexAreas(const MatX3d& V, const MatX3i& F);

// The geodesic variant of ComputeNaturalNeighbourWeights. A captured vertex
// u counts area(u) * min(1, (D(u) - T(u)) / h) (D: distance to the sites,
// T: distance to the inserted vertex, h: mean edge length), so the stolen
// area varies continuously from one vertex to the next.
NaturalNeighbourWeights ComputeGeodesicNaturalNeighbourWeights(
    const TriMesh& neutral, const std::vector<SurfacePoint>& sites);

}  // namespace hmc
