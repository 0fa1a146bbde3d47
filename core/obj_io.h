// Wavefront OBJ as DCC tools write it: triangles, quads and n-gons (fanned
// into triangles on load), `vt` texture coordinates with seams (several UVs
// per vertex), `vn` normals (read and ignored), groups, materials and
// comments (ignored), negative (relative) indices.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "core/mesh.h"

namespace hmc {

struct ObjReadOptions {
  bool require_uvs = false;  // throw if the file has no `vt`
  double scale = 1.0;        // multiply positions (cm -> mm: 10)
};

// Throws InputError with the file and line on malformed or truncated input,
// out-of-range indices, NaN/Inf coordinates.
TriMesh ReadObj(const std::filesystem::path& path,
                const ObjReadOptions& options = {});

// Writes atomically, positions with `precision` significant digits.
void WriteObj(const std::filesystem::path& path, const TriMesh& mesh,
              int precision = 9);

// The polygons of an OBJ as written in the file, for data that refers to the
// file's own faces (the markers of an actor package). Polygon p (the p-th
// `f` statement, 0-based) has corners[p] corners and became the triangles
// first_triangle[p] + j, j = 0 .. corners[p] - 3, fanned from its first
// corner: triangle j = corners (0, j + 1, j + 2).
struct ObjPolygons {
  std::vector<int> first_triangle;  // P: first triangle of each polygon
  std::vector<int> corners;         // P: corner count of each polygon (>= 3)

  int NumPolygons() const { return static_cast<int>(corners.size()); }
};

// ReadObj on text already in memory; `origin` names the file in errors.
// Fills `polygons` when given.
TriMesh ParseObj(std::string_view text, const std::filesystem::path& origin,
                 const ObjReadOptions& options = {},
                 ObjPolygons* polygons = nullptr);

// The OBJ text WriteObj writes, with the topology (F, UV, FUV) of `topology`
// and the positions `V` (topology.NumVertices() x 3, mm): a shape written as
// a full OBJ that a DCC opens. Throws InputError naming `origin` on a
// non-finite coordinate.
std::string FormatObj(const TriMesh& topology, const MatX3d& V, int precision,
                      const std::filesystem::path& origin);

// WriteObj with the positions V instead of topology.V.
void WriteObj(const std::filesystem::path& path, const TriMesh& topology,
              const MatX3d& V, int precision = 9);

}  // namespace hmc
