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

}  // namespace hmc
