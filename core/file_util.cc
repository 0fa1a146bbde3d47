#include "core/file_util.h"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <fstream>
#include <sstream>

#include "core/error.h"

namespace hmc {

void WriteFileAtomic(const std::filesystem::path& path,
                     const std::function<void(std::ostream&)>& write,
                     bool binary) {
  static std::atomic<int> counter{0};
  const std::filesystem::path dir =
      path.has_parent_path() ? path.parent_path() : ".";
  if (!std::filesystem::is_directory(dir)) {
    ThrowInputError(path, 0, "cannot write: folder {} does not exist",
                    dir.string());
  }
  const std::filesystem::path temp =
      dir / fmt::format(".{}.tmp.{}.{}", path.filename().string(), getpid(),
                        counter++);
  try {
    std::ofstream out(temp, binary ? std::ios::binary | std::ios::trunc
                                   : std::ios::trunc);
    if (!out) ThrowInputError(path, 0, "cannot open for writing");
    write(out);
    out.flush();
    if (!out) ThrowInputError(path, 0, "write failed (disk full?)");
    out.close();
    std::error_code error;
    std::filesystem::rename(temp, path, error);
    if (error) {
      ThrowInputError(path, 0, "cannot rename temporary file: {}",
                      error.message());
    }
  } catch (...) {
    std::error_code ignored;
    std::filesystem::remove(temp, ignored);
    throw;
  }
}

void WriteFileAtomic(const std::filesystem::path& path,
                     std::string_view contents) {
  WriteFileAtomic(
      path, [&](std::ostream& out) { out.write(contents.data(),
                                               contents.size()); },
      true);
}

std::string ReadFile(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    ThrowInputError(path, 0, std::filesystem::exists(path)
                                 ? "cannot open for reading"
                                 : "file does not exist");
  }
  // One sized read: several times faster than streaming through rdbuf on
  // the multi-megabyte OBJs of an actor package.
  in.seekg(0, std::ios::end);
  const std::streamoff size = in.tellg();
  in.seekg(0, std::ios::beg);
  std::string contents(static_cast<size_t>(std::max<std::streamoff>(size, 0)), '\0');
  if (size > 0 && !in.read(contents.data(), size)) {
    ThrowInputError(path, 0, "read failed");
  }
  return contents;
}

void EnsureDirectory(const std::filesystem::path& dir) {
  std::error_code error;
  std::filesystem::create_directories(dir, error);
  if (error) ThrowInputError(dir, 0, "cannot create folder: {}", error.message());
}

}  // namespace hmc
