// Wavefront OBJ as DCC tools write it: triangles, quads and n-gons (fanned
// into triangles on load), `vt` texture coordinates with seams (several UVs
// per vertex), `vn` normals (read and ignored), groups, materials and
// comments (ignored), negative (relative) indices.
#pragma once

#include <filesystem>

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

}  // namespace hmc
