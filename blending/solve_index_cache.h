// Everything the solve precomputes once per actor (docs/ARCHITECTURE.md, "Method steps",
// 3: "the index is cached on disk with a version header"): the unskinned
// shapes, the natural-neighbour weights and the local geometric index, and
// the versioned binary cache file in the actor package that holds the latter
// two.
//
// Cache file `lgi_index.bin`: the ShapeIndex block (magic "HMCLGIX", format
// version, Actor::content_hash, hash of the index and natural-neighbour
// options, per-bundle clouds, simplices and grids), then the
// natural-neighbour weights. Any mismatch or damage means "rebuild".
//
// Where it lives (docs/formats.md, "Local geometric index cache"): a solve
// never writes into its input. It reads `<actor>/lgi_index.bin` when present
// and valid (`hmc index --actor DIR --into_package` puts it there, for
// packages on read-only shared storage), else the user cache
// `$XDG_CACHE_HOME/hmc/<actor hash>-<options hash>/lgi_index.bin`
// ($HOME/.cache when XDG_CACHE_HOME is unset), else builds the model and
// writes it to the user cache. Writes are atomic (temporary file, then
// rename), so concurrent jobs on one package at worst both build it and
// the last rename wins with identical contents.
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

// Where a build writes the model it had to build.
enum class IndexCacheWrite {
  kNone,       // memory only
  kUserCache,  // the user cache (the solve's default)
  kPackage,    // the actor package (`hmc index --into_package`)
};

// <actor_dir>/lgi_index.bin.
std::filesystem::path IndexCachePath(const std::filesystem::path& actor_dir);
// $XDG_CACHE_HOME/hmc, else $HOME/.cache/hmc; empty when neither is set.
std::filesystem::path UserCacheRoot();
// <UserCacheRoot()>/<actor hash>-<options hash>/lgi_index.bin (16 hex
// digits each); empty without a user cache root.
std::filesystem::path UserIndexCachePath(const Actor& actor,
                                         uint64_t options_hash);

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

// Loads the package's cache, else the user cache, when valid; else builds
// the model and writes it where `write` says (a failed write to the user
// cache is a warning: the model stays in memory). An actor without a folder
// (in memory) has no package cache.
LgiModel LoadOrBuildLgiModel(const Actor& actor,
                             const IndexOptions& index_options,
                             const NaturalNeighbourOptions& nn_options,
                             IndexCacheWrite write);

}  // namespace hmc
