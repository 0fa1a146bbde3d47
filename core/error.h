// Three levels of failure (docs/ARCHITECTURE.md, "Contracts"):
//  - HMC_CHECK: a broken internal invariant; logs and aborts.
//  - InputError: bad input or a broken API precondition; carries the file,
//    the line (0 = whole file) and a human message. `main` prints it as one
//    line and exits non-zero.
//  - Options::Check(): returns false and logs the offending option.
#pragma once

#include <filesystem>
#include <stdexcept>
#include <string>

#include <fmt/format.h>

namespace hmc {

class InputError : public std::runtime_error {
 public:
  InputError(std::filesystem::path file, int line, const std::string& what);
  explicit InputError(const std::string& what);

  const std::filesystem::path& file() const { return file_; }
  int line() const { return line_; }

 private:
  std::filesystem::path file_;
  int line_ = 0;
};

// Throws InputError("file:line: message").
template <typename... Args>
[[noreturn]] void ThrowInputError(const std::filesystem::path& file, int line,
                                  fmt::format_string<Args...> format,
                                  Args&&... args) {
  throw InputError(file, line, fmt::format(format, std::forward<Args>(args)...));
}

[[noreturn]] void AbortOnInvariant(const char* condition, const char* file,
                                   int line, const std::string& message);

}  // namespace hmc

#define HMC_CHECK(condition)                                              \
  do {                                                                    \
    if (!(condition)) ::hmc::AbortOnInvariant(#condition, __FILE__,      \
                                              __LINE__, std::string());   \
  } while (false)

#define HMC_CHECK_MSG(condition, message)                                 \
  do {                                                                    \
    if (!(condition)) ::hmc::AbortOnInvariant(#condition, __FILE__,      \
                                              __LINE__, (message));       \
  } while (false)
