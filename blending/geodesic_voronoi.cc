#include "blending/geodesic_voronoi.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <tbb/enumerable_thread_specific.h>

#include "core/error.h"
#include "core/logging.h"
#include "core/parallel.h"

namespace hmc {

GeodesicVoronoi ComputeGeodesicVoronoi(const FastMarching& marching,
                                       const TriMesh& mesh,
                                       const std::vector<SurfacePoint>& sites) {
  std::vector<MarchSource> sources;
  for (size_t k = 0; k < sites.size(); ++k) {
    const SurfacePoint& s = sites[k];
    CheckSiteOnMesh(mesh, s, k);
    const Vec3 x = EvaluateSurfacePoint(s, mesh.F, mesh.V);
    for (int i = 0; i < 3; ++i) {
      const int v = mesh.F(s.face, i);
      sources.push_back({v, (mesh.V.row(v).transpose() - x).norm(),
                         static_cast<int>(k)});
    }
  }
  const FastMarching::Result march = marching.Run(sources);
  return {march.distance, march.label};
}

Eigen::VectorXd VertexAreas(const MatX3d& V, const MatX3i& F) {
  Eigen::VectorXd area = Eigen::VectorXd::Zero(V.rows());
  for (int f = 0; f < F.rows(); ++f) {
    const Vec3 a = V.row(F(f, 0)), b = V.row(F(f, 1)), c = V.row(F(f, 2));
    const double third = (b - a).cross(c - a).norm() / 6.0;
    for (int i = 0; i < 3; ++i) area[F(f, i)] += third;
  }
  return area;
}

NaturalNeighbourWeights ComputeGeodesicNaturalNeighbourWeights(
    const TriMesh& neutral, const std::vector<SurfacePoint>& sites) {
  const int num_sites = static_cast<int>(sites.size());
  const int num_vertices = neutral.NumVertices();
  const FastMarching marching(neutral.V, neutral.F);
  const GeodesicVoronoi voronoi = ComputeGeodesicVoronoi(marching, neutral, sites);
  const Eigen::VectorXd area = VertexAreas(neutral.V, neutral.F);

  double edge_sum = 0.0;
  for (int f = 0; f < neutral.NumFaces(); ++f) {
    for (int i = 0; i < 3; ++i) {
      edge_sum += (neutral.V.row(neutral.F(f, i)) -
                   neutral.V.row(neutral.F(f, (i + 1) % 3))).norm();
    }
  }
  const double ramp = std::max(edge_sum / std::max(1, 3 * neutral.NumFaces()), 1e-12);

  NaturalNeighbourWeights result;
  result.cell = voronoi.cell;
  // Vertices no site reaches (a separate mesh component): nearest site in 3D,
  // so that every row still sums to one.
  int unreached = 0;
  std::vector<Vec3> site_x;
  for (const SurfacePoint& s : sites) {
    site_x.push_back(EvaluateSurfacePoint(s, neutral.F, neutral.V));
  }
  for (int v = 0; v < num_vertices; ++v) {
    if (result.cell[v] >= 0) continue;
    ++unreached;
    double best = std::numeric_limits<double>::infinity();
    for (int k = 0; k < num_sites; ++k) {
      const double d = (site_x[k] - neutral.V.row(v).transpose()).norm();
      if (d < best) {
        best = d;
        result.cell[v] = k;
      }
    }
  }
  if (unreached > 0) {
    spdlog::warn("natural-neighbour weights: {} vertices are not connected to "
                 "any bundle on the mesh; they follow the nearest bundle in 3D",
                 unreached);
  }

  tbb::enumerable_thread_specific<FastMarching::Scratch> scratch;
  std::vector<std::vector<std::pair<int, double>>> stolen(num_vertices);
  Progress progress("natural-neighbour weights (geodesic)", num_vertices,
                    "vertices");
  ParallelFor(
      0, num_vertices,
      [&](int64_t v) {
        if (voronoi.cell[v] < 0) return;
        FastMarching::Scratch& s = scratch.local();
        marching.MarchBounded(static_cast<int>(v), voronoi.distance, &s);
        auto& areas = stolen[v];
        for (int u : s.accepted) {
          const int label = voronoi.cell[u];
          const double margin = voronoi.distance[u] - FastMarching::DistanceOf(s, u);
          const double w = area[u] * std::min(1.0, margin / ramp);
          if (!(w > 0)) continue;
          auto it = std::find_if(areas.begin(), areas.end(),
                                 [label](const auto& a) { return a.first == label; });
          if (it == areas.end()) {
            areas.emplace_back(label, w);
          } else {
            it->second += w;
          }
        }
        progress.Advance();
      },
      16);
  progress.Finish();
  result.weights = WeightsFromStolenAreas(stolen, result.cell, num_sites);

  std::vector<std::vector<char>> adjacent(num_sites,
                                          std::vector<char>(num_sites, 0));
  for (int f = 0; f < neutral.NumFaces(); ++f) {
    for (int i = 0; i < 3; ++i) {
      const int a = voronoi.cell[neutral.F(f, i)];
      const int b = voronoi.cell[neutral.F(f, (i + 1) % 3)];
      if (a >= 0 && b >= 0 && a != b) adjacent[a][b] = adjacent[b][a] = 1;
    }
  }
  result.site_neighbours.assign(num_sites, {});
  for (int a = 0; a < num_sites; ++a) {
    for (int b = 0; b < num_sites; ++b) {
      if (adjacent[a][b]) result.site_neighbours[a].push_back(b);
    }
  }
  return result;
}

}  // namespace hmc
