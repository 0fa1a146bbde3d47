// `hmc index --actor DIR [--force] [--into_package] [--json]`: builds the
// local geometric index of an actor (point clouds, tetrahedra, grids) and
// its natural-neighbour weights, caches them (lgi_index.bin, rebuilt when
// the actor's files or these options change) in the user cache, or with
// --into_package in the package itself (blending/solve_index_cache.h), and
// prints per-bundle statistics and totals (--json: one JSON object instead).
#include <cstdio>
#include <memory>
#include <string>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "apps/command.h"
#include "blending/solve_index_cache.h"
#include "core/actor.h"
#include "core/file_util.h"
#include "core/logging.h"

namespace hmc {
namespace {

struct IndexCommand {
  std::string actor_dir;
  bool force = false;
  bool into_package = false;
  bool json = false;
  LgiBuildOptions options;
};

void PrintStatistics(const Actor& actor, const LgiModel& model, bool json) {
  const ShapeIndex& index = model.index;
  if (!json) fmt::print("{:<24} {:>6} {:>6} {:>6} {:>6} {:>10} {:>9} {:>7} {:>6} {:>9} "
             "{:>9}\n",
             "bundle", "points", "still", "tags", "merged", "tets_all",
             "tets_kept", "tris", "edges", "grid", "memory_kB");
  int64_t points = 0, all = 0, kept = 0, tris = 0, edges = 0, cells = 0,
          memory = 0;
  nlohmann::json bundles = nlohmann::json::array();
  for (size_t k = 0; k < index.bundles.size(); ++k) {
    const BundleIndexStats& s = index.bundles[k].stats();
    const CloudStats& c = index.clouds[k];
    const std::string grid = fmt::format("{}x{}x{}", s.grid_cells[0],
                                         s.grid_cells[1], s.grid_cells[2]);
    if (!json) fmt::print("{:<24} {:>6} {:>6} {:>6} {:>6} {:>10} {:>9} {:>7} {:>6} {:>9} "
               "{:>9.1f}\n",
               actor.markers[k].name, s.points, c.pruned_motion, c.pruned_tags,
               c.merged, s.tets_candidate, s.tets_kept, s.triangles_kept,
               s.edges_kept, grid, s.memory_bytes / 1024.0);
    points += s.points;
    all += s.tets_candidate;
    kept += s.tets_kept;
    tris += s.triangles_kept;
    edges += s.edges_kept;
    cells += int64_t(s.grid_cells[0]) * s.grid_cells[1] * s.grid_cells[2];
    memory += s.memory_bytes;
    bundles.push_back({{"marker", actor.markers[k].name},
                       {"points", s.points},
                       {"shapes_pruned_motion", c.pruned_motion},
                       {"shapes_pruned_tags", c.pruned_tags},
                       {"shapes_merged", c.merged},
                       {"tets_candidate", s.tets_candidate},
                       {"tets_kept", s.tets_kept},
                       {"triangles_kept", s.triangles_kept},
                       {"edges_kept", s.edges_kept},
                       {"grid_cells", s.grid_cells},
                       {"grid_entries", s.grid_entries},
                       {"memory_bytes", s.memory_bytes}});
  }
  if (!json) fmt::print("total: {} bundles, {} points, tetrahedra {} -> {} kept ({:.2f}%), "
             "{} triangles, {} edges, {} grid cells, {:.1f} MB; {}\n",
             index.bundles.size(), points, all, kept,
             all > 0 ? 100.0 * kept / all : 0.0, tris, edges, cells,
             memory / 1048576.0,
             model.from_cache ? "loaded from the cache"
                              : fmt::format("built in {:.2f} s",
                                            model.build_seconds));
  if (json) {
    const nlohmann::json report = {
        {"actor", actor.name},
        {"from_cache", model.from_cache},
        {"build_seconds", model.build_seconds},
        {"totals",
         {{"bundles", index.bundles.size()},
          {"points", points},
          {"tets_candidate", all},
          {"tets_kept", kept},
          {"triangles_kept", tris},
          {"edges_kept", edges},
          {"grid_cells", cells},
          {"memory_bytes", memory}}},
        {"bundles", bundles}};
    fmt::print("{}\n", report.dump());
  }
}

}  // namespace

HMC_COMMAND(Index, "", "index",
            "Build the local geometric index of an actor and cache it "
            "(user cache, or the package with --into_package)") {
  auto cmd = std::make_shared<IndexCommand>();
  app->add_option("--actor", cmd->actor_dir, "Actor package folder")
      ->required()
      ->check(CLI::ExistingDirectory);
  app->add_flag("--force", cmd->force, "Rebuild even if the cache is valid");
  app->add_flag("--into_package", cmd->into_package,
                "Write the cache into the actor package (lgi_index.bin), "
                "where every later solve reads it");
  app->add_flag("--json", cmd->json,
                "Print one JSON object instead of the table");
  auto binding = BindOptions(app, &cmd->options);
  return [cmd, binding] {
    binding->Apply();
    RequireValid(cmd->options, "index");
    const Actor actor = LoadActor(cmd->actor_dir);
    StageTimer timer("index");
    LgiModel model;
    const IndexCacheWrite write = cmd->into_package
                                      ? IndexCacheWrite::kPackage
                                      : IndexCacheWrite::kUserCache;
    if (cmd->force) {
      model = BuildLgiModel(actor, cmd->options.index, cmd->options.nn);
      const std::filesystem::path path =
          write == IndexCacheWrite::kPackage
              ? IndexCachePath(actor.dir)
              : UserIndexCachePath(actor, model.index.options_hash);
      if (!path.empty()) {
        EnsureDirectory(path.parent_path());
        WriteLgiCache(path, model);
      }
    } else {
      model = LoadOrBuildLgiModel(actor, cmd->options.index, cmd->options.nn,
                                  write);
    }
    PrintStatistics(actor, model, cmd->json);
    return 0;
  };
}

}  // namespace hmc
