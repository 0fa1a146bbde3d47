// Everything the solve precomputes once per actor (DESIGN.md section 4, step
// 3: "the index is cached on disk with a version header"): the unskinned
// shapes, the natural-neighbour weights and the local geometric index, and
// the versioned binary cache file in the actor package that holds the latter
// two.
//
// Cache file `<actor>/lgi_index.bin`: the ShapeIndex block (magic
// "HMCLGIX", format version, Actor::content_hash, hash of the index and
// natural-neighbour options, per-bundle clouds, simplices and grids), then
// the natural-neighbour weights. Any mismatch or damage means "rebuild".
#pragma once

#include <filesystem>
#include <optional>

#include "blending/natural_neighbour.h"
#include "core/actor.h"
#include "indexing/index_options.h"
#include "indexing/shape_data.h"
#include "indexing/shape_index.h"

namespace hmc {

// The options that shape the cached data: the index (group "index") and the
// natural-neighbour weights (group "nn").
struct LgiBuildOptions {
  IndexOptions index;
  NaturalNeighbourOptions nn;

  void Register(OptionFields* fields);
  bool Check() const { return index.Check() && nn.Check(); }
};

struct LgiModel {
  ShapeData data;
  NaturalNeighbourWeights nn;
  ShapeIndex index;
  bool from_cache = false;
  double build_seconds = 0.0;  // index + weights (0 when loaded)
};

std::filesystem::path IndexCachePath(const std::filesystem::path& actor_dir);

// Hash of the options that change the cached data.
uint64_t IndexOptionsHash(const IndexOptions& index_options,
                          const NaturalNeighbourOptions& nn_options);

// K lists of the vertices where each bundle's weight is > 0.
std::vector<std::vector<int>> RegionsOfInfluence(
    const NaturalNeighbourWeights& nn);

// Builds the weights and the index from scratch (parallel).
LgiModel BuildLgiModel(const Actor& actor, const IndexOptions& index_options,
                       const NaturalNeighbourOptions& nn_options);

// The cache at `path` if it exists and matches the actor and the options;
// otherwise nullopt (and logs why at info level).
std::optional<LgiModel> LoadLgiCache(const std::filesystem::path& path,
                                     const Actor& actor,
                                     const IndexOptions& index_options,
                                     const NaturalNeighbourOptions& nn_options);

// Writes the cache atomically.
void WriteLgiCache(const std::filesystem::path& path, const LgiModel& model);

// Loads the cache when valid, else builds and (if `write_cache` and the
// actor has a folder) writes it.
LgiModel LoadOrBuildLgiModel(const Actor& actor,
                             const IndexOptions& index_options,
                             const NaturalNeighbourOptions& nn_options,
                             bool write_cache);

}  // namespace hmc
