// The process cache of loaded actors (core/actor_cache.h).
#include <atomic>
#include <map>
#include <mutex>
#include <optional>

#include <spdlog/spdlog.h>

#include "core/actor_cache.h"
#include "core/actor_io.h"
#include "core/error.h"
#include "core/file_util.h"
#include "core/hash.h"
#include "core/logging.h"
#include "core/parallel.h"

namespace hmc {

namespace {

std::atomic<bool> cache_on{false};
std::mutex cache_mutex;

struct CachedActor {
  uint64_t contents = 0;
  std::shared_ptr<const Actor> actor;
};

std::map<std::string, CachedActor>& Cache() {
  static std::map<std::string, CachedActor> cache;
  return cache;
}

// The hash of actor.yaml and of every file it lists (name and contents),
// read now; nullopt when the package cannot be read that far (the parse
// then reports what is wrong).
std::optional<uint64_t> PackageContents(const std::filesystem::path& dir) {
  try {
    const std::filesystem::path yaml_file = dir / actor_io::kYamlFile;
    const std::string yaml_text = ReadFile(yaml_file);
    const actor_io::PackageEntry entry = actor_io::ParseActorYaml(yaml_text, yaml_file);
    std::vector<std::filesystem::path> files = {entry.neutral, entry.markers};
    if (entry.jaw_rig) files.push_back(entry.jaw_rig->weights);
    for (const actor_io::ShapeEntry& shape : entry.shapes) files.push_back(shape.file);
    std::vector<uint64_t> hashes(files.size(), 0);
    ParallelFor(0, static_cast<int64_t>(files.size()),
                [&](int64_t i) { hashes[i] = HashFile(dir / files[i]); });
    ContentHasher hasher;
    hasher.Update(yaml_text);
    for (size_t i = 0; i < files.size(); ++i) {
      hasher.Update(files[i].generic_string());
      hasher.Update(HashHex(hashes[i]));
    }
    return hasher.Digest();
  } catch (const InputError&) {
    return std::nullopt;
  }
}

}  // namespace

void EnableActorCache(bool on) {
  cache_on = on;
  if (!on) {
    const std::lock_guard<std::mutex> lock(cache_mutex);
    Cache().clear();
  }
}

std::shared_ptr<const Actor> LoadActorShared(const std::filesystem::path& dir) {
  if (!cache_on) return std::make_shared<const Actor>(actor_io::LoadActorPackage(dir));
  const std::string key = dir.string();
  const std::optional<uint64_t> contents = PackageContents(dir);
  if (contents) {
    const std::lock_guard<std::mutex> lock(cache_mutex);
    const auto it = Cache().find(key);
    if (it != Cache().end() && it->second.contents == *contents) {
      spdlog::info("actor '{}' ({}): files unchanged since this process loaded them: not "
                   "parsed again",
                   it->second.actor->name, key);
      return it->second.actor;
    }
  }
  auto actor = std::make_shared<const Actor>(actor_io::LoadActorPackage(dir));
  if (contents) {
    const std::lock_guard<std::mutex> lock(cache_mutex);
    Cache()[key] = {*contents, actor};
  }
  return actor;
}

Actor LoadActor(const std::filesystem::path& dir) {
  if (!cache_on) return actor_io::LoadActorPackage(dir);
  return *LoadActorShared(dir);
}

}  // namespace hmc
