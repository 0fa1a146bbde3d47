// Small procedural meshes for the blending tests and benchmark (header-only:
// no library code depends on it).
#pragma once

#include <array>
#include <cmath>
#include <map>
#include <random>
#include <utility>
#include <vector>

#include "core/mesh.h"

namespace hmc {
namespace testing_meshes {

// An n x n vertex grid over [0, size]^2 in the z = 0 plane (mm), UV = the
// position / size. Cells are split along alternating diagonals. `hole`:
// remove the triangles whose centroid lies in the ellipse centred at
// (0.5, 0.35) with radii (0.18, 0.05) in UV (a "mouth"). `bump`: height of a
// smooth dome (mm), so that 3D and UV distances differ.
inline TriMesh MakeGrid(int n, double size, bool hole = false,
                        double bump = 0.0) {
  TriMesh mesh;
  mesh.V.resize(n * n, 3);
  mesh.UV.resize(n * n, 2);
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) {
      const double u = static_cast<double>(x) / (n - 1);
      const double v = static_cast<double>(y) / (n - 1);
      const double r2 = (u - 0.5) * (u - 0.5) + (v - 0.5) * (v - 0.5);
      mesh.V.row(y * n + x) << u * size, v * size, bump * std::exp(-4.0 * r2);
      mesh.UV.row(y * n + x) << u, v;
    }
  }
  std::vector<std::array<int, 3>> faces;
  for (int y = 0; y + 1 < n; ++y) {
    for (int x = 0; x + 1 < n; ++x) {
      const int a = y * n + x, b = a + 1, c = a + n, d = c + 1;
      std::array<std::array<int, 3>, 2> cell;
      if ((x + y) % 2 == 0) {
        cell = {{{a, b, d}, {a, d, c}}};
      } else {
        cell = {{{a, b, c}, {b, d, c}}};
      }
      for (const auto& f : cell) {
        if (hole) {
          double cu = 0, cv = 0;
          for (int i : f) {
            cu += mesh.UV(i, 0) / 3;
            cv += mesh.UV(i, 1) / 3;
          }
          const double e = std::pow((cu - 0.5) / 0.18, 2) + std::pow((cv - 0.35) / 0.05, 2);
          if (e < 1.0) continue;
        }
        faces.push_back(f);
      }
    }
  }
  mesh.F.resize(faces.size(), 3);
  for (size_t f = 0; f < faces.size(); ++f) {
    mesh.F.row(f) << faces[f][0], faces[f][1], faces[f][2];
  }
  mesh.FUV = mesh.F;
  return mesh;
}

// Icosahedron subdivided `levels` times, projected on a sphere of `radius`
// (mm) centred at the origin. No UVs.
inline TriMesh MakeIcosphere(int levels, double radius) {
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  std::vector<Vec3> v = {{-1, t, 0}, {1, t, 0},  {-1, -t, 0}, {1, -t, 0},
                         {0, -1, t}, {0, 1, t},  {0, -1, -t}, {0, 1, -t},
                         {t, 0, -1}, {t, 0, 1},  {-t, 0, -1}, {-t, 0, 1}};
  std::vector<std::array<int, 3>> f = {
      {0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
      {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
      {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
      {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  for (auto& p : v) p.normalize();
  for (int level = 0; level < levels; ++level) {
    std::map<std::pair<int, int>, int> midpoint;
    auto mid = [&](int a, int b) {
      const auto key = std::minmax(a, b);
      auto it = midpoint.find(key);
      if (it != midpoint.end()) return it->second;
      v.push_back((v[a] + v[b]).normalized());
      midpoint[key] = static_cast<int>(v.size()) - 1;
      return static_cast<int>(v.size()) - 1;
    };
    std::vector<std::array<int, 3>> next;
    for (const auto& tri : f) {
      const int ab = mid(tri[0], tri[1]), bc = mid(tri[1], tri[2]),
                ca = mid(tri[2], tri[0]);
      next.push_back({tri[0], ab, ca});
      next.push_back({tri[1], bc, ab});
      next.push_back({tri[2], ca, bc});
      next.push_back({ab, bc, ca});
    }
    f = std::move(next);
  }
  TriMesh mesh;
  mesh.V.resize(v.size(), 3);
  for (size_t i = 0; i < v.size(); ++i) mesh.V.row(i) = radius * v[i].transpose();
  mesh.F.resize(f.size(), 3);
  for (size_t i = 0; i < f.size(); ++i) mesh.F.row(i) << f[i][0], f[i][1], f[i][2];
  return mesh;
}

// `count` random sites on random triangles of `mesh` whose centroid UV lies
// in [lo, hi]^2 (all triangles when the mesh has no UVs), with random
// barycentrics.
inline std::vector<SurfacePoint> RandomSites(const TriMesh& mesh, int count,
                                             unsigned seed, double lo = 0.0,
                                             double hi = 1.0) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> face(0, mesh.NumFaces() - 1);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<SurfacePoint> sites;
  while (static_cast<int>(sites.size()) < count) {
    SurfacePoint s;
    s.face = face(rng);
    if (mesh.HasUVs()) {
      Vec2 c = Vec2::Zero();
      for (int i = 0; i < 3; ++i) c += mesh.UV.row(mesh.FUV(s.face, i)).transpose() / 3;
      if (c.minCoeff() < lo || c.maxCoeff() > hi) continue;
    }
    double a = unit(rng), b = unit(rng);
    if (a + b > 1) {
      a = 1 - a;
      b = 1 - b;
    }
    s.bary = Vec3(a, b, 1 - a - b);
    sites.push_back(s);
  }
  return sites;
}

}  // namespace testing_meshes
}  // namespace hmc
