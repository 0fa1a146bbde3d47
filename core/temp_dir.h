// A fresh folder under the system temp directory, removed with everything in
// it when the object goes out of scope. For tests and scratch work.
#pragma once

#include <unistd.h>

#include <filesystem>
#include <string>
#include <system_error>

#include <fmt/format.h>

namespace hmc {

class TempDir {
 public:
  explicit TempDir(const std::string& prefix = "hmc") {
    static int counter = 0;
    path_ = std::filesystem::temp_directory_path() /
            fmt::format("{}_{}_{}", prefix, getpid(), counter++);
    std::filesystem::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ignored;
    std::filesystem::remove_all(path_, ignored);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;

  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

}  // namespace hmc
