// Shared pieces of the libFuzzer harnesses (docs/reliability.md, "Fuzzing").
// A harness feeds the fuzzer's bytes to one parser, as text in memory or as
// a file (the readers that take a path get a per-process file in $TMPDIR).
// InputError is the parser's way to refuse input and is expected; anything
// else that escapes (another exception, a sanitizer report, a hang, an
// allocation beyond libFuzzer's -rss_limit_mb) is a finding.
#pragma once

#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "core/error.h"

namespace hmc::fuzz {

inline std::filesystem::path ScratchDir() {
  static const std::filesystem::path dir = [] {
    const char* tmp = std::getenv("TMPDIR");
    const std::filesystem::path d = std::filesystem::path(tmp ? tmp : "/tmp") /
                                    fmt::format("hmc_fuzz_{}", getpid());
    std::filesystem::create_directories(d);
    spdlog::set_level(spdlog::level::off);
    return d;
  }();
  return dir;
}

// Writes the input to ScratchDir()/name and returns the path.
inline std::filesystem::path WriteInput(const uint8_t* data, size_t size,
                                        const std::string& name) {
  const std::filesystem::path path = ScratchDir() / name;
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  return path;
}

inline std::string Text(const uint8_t* data, size_t size) {
  return std::string(reinterpret_cast<const char*>(data), size);
}

// Runs fn; an InputError is a refusal, not a finding.
template <typename Fn>
int Refusable(Fn&& fn) {
  try {
    fn();
  } catch (const InputError&) {
  }
  return 0;
}

}  // namespace hmc::fuzz
