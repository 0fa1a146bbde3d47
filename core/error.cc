#include "core/error.h"

#include <cstdlib>

#include <spdlog/spdlog.h>

namespace hmc {
namespace {

std::string Locate(const std::filesystem::path& file, int line,
                   const std::string& what) {
  if (file.empty()) return what;
  if (line > 0) return fmt::format("{}:{}: {}", file.string(), line, what);
  return fmt::format("{}: {}", file.string(), what);
}

}  // namespace

InputError::InputError(std::filesystem::path file, int line,
                       const std::string& what)
    : std::runtime_error(Locate(file, line, what)),
      file_(std::move(file)),
      line_(line) {}

InputError::InputError(const std::string& what) : std::runtime_error(what) {}

void AbortOnInvariant(const char* condition, const char* file, int line,
                      const std::string& message) {
  spdlog::critical("internal error at {}:{}: check failed: {} {}", file, line,
                   condition, message);
  std::abort();
}

}  // namespace hmc
