// Runs the built `hmc` CLI (HMC_BINARY) from integration tests, as a user
// would from a shell, and captures what it printed.
#pragma once

#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <string>

#include <fmt/format.h>

#include "core/file_util.h"

namespace hmc {

struct CliResult {
  int exit_code = -1;
  std::string out;  // standard output
  std::string err;  // standard error
};

// `arguments` are appended to the binary's path as shell words; stdout and
// stderr go through files in `scratch`. The user cache (XDG_CACHE_HOME) is
// scratch/xdg_cache, so tests neither share nor leave caches behind.
inline CliResult RunHmc(const std::string& arguments,
                        const std::filesystem::path& scratch) {
  const std::filesystem::path out = scratch / "stdout.txt";
  const std::filesystem::path err = scratch / "stderr.txt";
  const std::string command = fmt::format(
      "XDG_CACHE_HOME='{}' '{}' {} >'{}' 2>'{}'",
      (scratch / "xdg_cache").string(), HMC_BINARY, arguments, out.string(),
      err.string());
  const int status = std::system(command.c_str());
  CliResult result;
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  result.out = ReadFile(out);
  result.err = ReadFile(err);
  return result;
}

// The small actor most CLI tests share (seed 7, 96 x 80, no in-betweens or
// combinations: quick to index), written to `out`.
inline CliResult SynthTestActor(const std::filesystem::path& out,
                                const std::filesystem::path& scratch) {
  return RunHmc(fmt::format("actor synth --out '{}' --seed 7 --grid_u 96 --grid_v 80 "
                            "--dataset_inbetweens false --dataset_combos false",
                            out.string()),
                scratch);
}

// A short shot of `actor` with no contact sheet; `extra`: more flags.
inline CliResult SynthTestShot(const std::filesystem::path& actor,
                               const std::filesystem::path& out, int frames, int seed,
                               const std::filesystem::path& scratch,
                               const std::string& extra = "") {
  return RunHmc(fmt::format("synth shot --actor '{}' --out '{}' --frames {} --seed {} "
                            "--contact_frames 0 {}",
                            actor.string(), out.string(), frames, seed, extra),
                scratch);
}

}  // namespace hmc
