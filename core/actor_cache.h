// The process cache of loaded actors (core/actor_cache.cc). `hmc run` runs
// every stage's command in one process (docs/pipeline.md), and each would
// parse the same package again (about a second for the default actor).
// With the cache on, LoadActor (core/actor.h) still reads and hashes every
// file of the package (actor.yaml and each file it lists) and returns what
// an earlier load of the same folder (as spelled) parsed when all those
// contents are unchanged; else it parses the package and keeps the result.
// So a stage gets exactly what parsing the files now would give. Off by
// default: every command parses.
#pragma once

#include <filesystem>
#include <memory>

#include "core/actor.h"

namespace hmc {

// Turns the cache on or off (off also empties it).
void EnableActorCache(bool on);

// LoadActor without the copy: the cached actor itself (a fresh one when the
// cache is off).
std::shared_ptr<const Actor> LoadActorShared(const std::filesystem::path& dir);

}  // namespace hmc
