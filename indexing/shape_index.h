// The local geometric index of an actor (docs/ARCHITECTURE.md, "Method steps", 1-3):
// one point cloud per bundle, pruned and merged, with its non-manifold
// tetrahedra and grid (BundleIndex). Built once per actor and cached.
#pragma once

#include <cstdint>
#include <iosfwd>
#include <vector>

#include "core/actor.h"
#include "indexing/bundle_index.h"
#include "indexing/index_options.h"
#include "indexing/shape_data.h"

namespace hmc {

struct CloudStats {
  int shapes = 0;         // dataset shapes considered
  int pruned_motion = 0;  // do not move the region beyond merge_mm
  int pruned_tags = 0;    // region tags exclude them, motion <= region_tag_mm
  int merged = 0;         // near-duplicates of a kept shape over the region
};

struct ShapeIndex {
  std::vector<BundleIndex> bundles;  // K, in marker order
  std::vector<CloudStats> clouds;    // K
  // K x P lists: the shapes each cloud point stands for (its own, -1 for
  // the neutral, and the shapes merged into it or pruned as not moving the
  // region), sorted.
  std::vector<std::vector<std::vector<int>>> represented;
  uint64_t actor_hash = 0;           // Actor::content_hash it was built from
  uint64_t options_hash = 0;         // hash of the options it was built with

  int64_t MemoryBytes() const;
  // Writes / reads the versioned binary block (magic, version, hashes, then
  // the bundles). Read throws InputError on a bad or truncated block.
  void Write(std::ostream& out) const;
  static ShapeIndex Read(std::istream& in);
};

// regions: K lists of vertices, each bundle's region of influence (where its
// natural-neighbour weight is > 0); pruning and merging compare shapes over
// it. An empty list falls back to the vertices of the bundle's triangle.
// Parallel over bundles.
ShapeIndex BuildShapeIndex(const Actor& actor, const ShapeData& data,
                           const std::vector<std::vector<int>>& regions,
                           const IndexOptions& options);

// Whether the marker's region tags exclude the shape: the shape has tags and
// none of them is among the marker's.
bool RegionTagsExclude(const Marker& marker, const Shape& shape);

// FNV-1a 64 of a byte string (cache keys).
uint64_t Fnv1a64(const std::string& bytes, uint64_t seed = 1469598103934665603ull);

}  // namespace hmc
