#include "core/file_util.h"

#include <fcntl.h>
#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>

#include "core/error.h"

namespace hmc {
namespace {

namespace fs = std::filesystem;

// Flushes a file's (or folder's) data to the disk, so a rename that
// survives a power cut never names a file whose contents did not.
void SyncPath(const fs::path& path, bool directory) {
  const int fd = ::open(path.c_str(), directory ? O_RDONLY | O_DIRECTORY : O_RDONLY);
  if (fd < 0) return;  // best effort: some file systems refuse folders
  ::fsync(fd);
  ::close(fd);
}

// Removes `.NAME.tmp.PID.N` files of `path` left by a process that no
// longer runs (killed mid-write): they are never renamed into place.
void RemoveStaleTemporaries(const fs::path& dir, const std::string& name) {
  const std::string prefix = "." + name + ".tmp.";
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string file = it->path().filename().string();
    if (file.compare(0, prefix.size(), prefix) != 0) continue;
    const std::string rest = file.substr(prefix.size());
    const size_t dot = rest.find('.');
    if (dot == std::string::npos) continue;
    char* end_ptr = nullptr;
    const long pid = std::strtol(rest.c_str(), &end_ptr, 10);
    if (end_ptr != rest.c_str() + dot || pid <= 0) continue;
    if (pid == getpid()) continue;  // ours, being written by another thread
    if (::kill(static_cast<pid_t>(pid), 0) == 0 || errno != ESRCH) continue;
    std::error_code ignored;
    fs::remove(it->path(), ignored);
  }
}

}  // namespace

std::string DescribeUnreadable(const fs::path& path) {
  std::error_code ec;
  const fs::file_status link = fs::symlink_status(path, ec);
  if (ec || link.type() == fs::file_type::not_found) return "does not exist";
  const fs::file_status status = fs::status(path, ec);
  if (ec) {
    if (ec == std::errc::too_many_symbolic_link_levels) return "is a loop of symbolic links";
    if (link.type() == fs::file_type::symlink) return "is a symbolic link to nothing";
    return "cannot be read: " + ec.message();
  }
  switch (status.type()) {
    case fs::file_type::regular: return "";
    case fs::file_type::directory: return "is a folder, not a file";
    case fs::file_type::fifo: return "is a FIFO (named pipe), not a file";
    case fs::file_type::socket: return "is a socket, not a file";
    case fs::file_type::character:
    case fs::file_type::block: return "is a device, not a file";
    case fs::file_type::not_found: return "is a symbolic link to nothing";
    default: return "is not a regular file";
  }
}

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
  RemoveStaleTemporaries(dir, path.filename().string());
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
    SyncPath(temp, false);
    std::error_code error;
    std::filesystem::rename(temp, path, error);
    if (error) {
      ThrowInputError(path, 0, "cannot rename temporary file: {}",
                      error.message());
    }
    SyncPath(dir, true);
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
  const std::string unreadable = DescribeUnreadable(path);
  if (!unreadable.empty()) ThrowInputError(path, 0, "{}", unreadable);
  std::ifstream in(path, std::ios::binary);
  if (!in) ThrowInputError(path, 0, "cannot open for reading: {}", std::strerror(errno));
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
