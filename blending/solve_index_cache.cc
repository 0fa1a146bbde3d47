#include "blending/solve_index_cache.h"

#include <chrono>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include <fmt/format.h>

#include "core/error.h"
#include "core/file_util.h"
#include "core/logging.h"

namespace hmc {

void LgiBuildOptions::Register(OptionFields* fields) {
  index.Register(fields);
  fields->SetGroup("nn");
  nn.Register(fields);
  fields->SetGroup("");
}

std::filesystem::path IndexCachePath(const std::filesystem::path& actor_dir) {
  return actor_dir / "lgi_index.bin";
}

std::filesystem::path UserCacheRoot() {
  const char* xdg = std::getenv("XDG_CACHE_HOME");
  if (xdg && *xdg) return std::filesystem::path(xdg) / "hmc";
  const char* home = std::getenv("HOME");
  if (home && *home) return std::filesystem::path(home) / ".cache" / "hmc";
  return {};
}

std::filesystem::path UserIndexCachePath(const Actor& actor,
                                         uint64_t options_hash) {
  const std::filesystem::path root = UserCacheRoot();
  if (root.empty()) return {};
  return root / fmt::format("{:016x}-{:016x}", actor.content_hash,
                            options_hash) /
         "lgi_index.bin";
}

uint64_t IndexOptionsHash(const IndexOptions& index_options,
                          const NaturalNeighbourOptions& nn_options) {
  IndexOptions io = index_options;
  NaturalNeighbourOptions no = nn_options;
  OptionFields fields;
  io.Register(&fields);
  no.Register(&fields);
  std::ostringstream text;
  for (const auto& field : fields.fields()) {
    text << field.name << '=' << fields.ValueString(field) << '\n';
  }
  return Fnv1a64(text.str());
}

std::vector<std::vector<int>> RegionsOfInfluence(
    const NaturalNeighbourWeights& nn) {
  std::vector<std::vector<int>> regions(nn.weights.cols());
  for (int v = 0; v < nn.weights.rows(); ++v) {
    for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(
             nn.weights, v);
         it; ++it) {
      if (it.value() > 0) regions[it.col()].push_back(v);
    }
  }
  return regions;
}

LgiModel BuildLgiModel(const Actor& actor, const IndexOptions& index_options,
                       const NaturalNeighbourOptions& nn_options) {
  const auto start = std::chrono::steady_clock::now();
  LgiModel model;
  model.data = ComputeShapeData(actor);
  {
    StageTimer timer("natural-neighbour weights");
    model.nn = ComputeNaturalNeighbourWeights(actor.neutral, model.data.sites,
                                              nn_options);
  }
  {
    StageTimer timer("local geometric index");
    model.index = BuildShapeIndex(actor, model.data,
                                  RegionsOfInfluence(model.nn), index_options);
  }
  model.index.options_hash = IndexOptionsHash(index_options, nn_options);
  model.build_seconds = std::chrono::duration<double>(
                            std::chrono::steady_clock::now() - start)
                            .count();
  return model;
}

std::optional<LgiModel> LoadLgiCache(const std::filesystem::path& path,
                                     const Actor& actor,
                                     const IndexOptions& index_options,
                                     const NaturalNeighbourOptions& nn_options) {
  if (!std::filesystem::exists(path)) {
    spdlog::info("index cache {}: none", path.string());
    return std::nullopt;
  }
  std::ifstream in(path, std::ios::binary);
  LgiModel model;
  try {
    model.index = ShapeIndex::Read(in);
    if (model.index.actor_hash != actor.content_hash) {
      spdlog::info("index cache {}: actor changed, rebuilding", path.string());
      return std::nullopt;
    }
    if (model.index.options_hash !=
        IndexOptionsHash(index_options, nn_options)) {
      spdlog::info("index cache {}: options changed, rebuilding",
                   path.string());
      return std::nullopt;
    }
    model.nn = NaturalNeighbourWeights::Read(in);
  } catch (const std::exception& e) {
    spdlog::warn("index cache {}: unreadable ({}), rebuilding", path.string(),
                 e.what());
    return std::nullopt;
  }
  const int K = static_cast<int>(actor.markers.size());
  const int N = static_cast<int>(actor.shapes.size());
  bool ok = static_cast<int>(model.index.bundles.size()) == K &&
            model.nn.weights.rows() == actor.NumVertices() &&
            model.nn.weights.cols() == K &&
            static_cast<int>(model.nn.site_neighbours.size()) == K;
  for (const auto& b : model.index.bundles) {
    for (int s : b.point_shapes()) ok = ok && s >= -1 && s < N;
  }
  for (const auto& list : model.nn.site_neighbours) {
    for (int j : list) ok = ok && j >= 0 && j < K;
  }
  if (!ok) {
    spdlog::warn("index cache {}: does not fit the actor, rebuilding",
                 path.string());
    return std::nullopt;
  }
  model.data = ComputeShapeData(actor);
  model.from_cache = true;
  return model;
}

void WriteLgiCache(const std::filesystem::path& path, const LgiModel& model) {
  WriteFileAtomic(
      path,
      [&](std::ostream& out) {
        model.index.Write(out);
        model.nn.Write(out);
      },
      /*binary=*/true);
}

LgiModel LoadOrBuildLgiModel(const Actor& actor,
                             const IndexOptions& index_options,
                             const NaturalNeighbourOptions& nn_options,
                             IndexCacheWrite write) {
  const std::filesystem::path package =
      actor.dir.empty() ? std::filesystem::path() : IndexCachePath(actor.dir);
  const std::filesystem::path user = UserIndexCachePath(
      actor, IndexOptionsHash(index_options, nn_options));
  for (const auto& path : {package, user}) {
    if (path.empty()) continue;
    if (auto cached = LoadLgiCache(path, actor, index_options, nn_options)) {
      spdlog::info("index cache {}: loaded", path.string());
      return std::move(*cached);
    }
  }
  LgiModel model = BuildLgiModel(actor, index_options, nn_options);
  if (write == IndexCacheWrite::kPackage && !package.empty()) {
    WriteLgiCache(package, model);
    spdlog::info("index cache {}: written", package.string());
  } else if (write == IndexCacheWrite::kUserCache && !user.empty()) {
    try {
      EnsureDirectory(user.parent_path());
      WriteLgiCache(user, model);
      spdlog::info("index cache {}: written", user.string());
    } catch (const InputError& e) {
      spdlog::warn("index cache not written ({}); kept in memory", e.what());
    }
  }
  return model;
}

}  // namespace hmc
