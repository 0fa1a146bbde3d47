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
#include "core/text.h"

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

namespace {

// The absolute path with links and `..` resolved as far as it exists.
fs::path Resolved(const fs::path& path) {
  std::error_code ec;
  const fs::path absolute = fs::absolute(path, ec);
  if (ec) return path.lexically_normal();
  const fs::path resolved = fs::weakly_canonical(absolute, ec);
  return ec ? absolute.lexically_normal() : resolved;
}

// True if `inner` is `outer` or lies inside it (both resolved).
bool IsWithin(const fs::path& inner, const fs::path& outer) {
  auto i = inner.begin();
  for (auto o = outer.begin(); o != outer.end(); ++o, ++i) {
    if (o->empty()) continue;  // a trailing separator
    if (i == inner.end() || *i != *o) return false;
  }
  return true;
}

}  // namespace

void CheckOutputApartFromInputs(const fs::path& output, const std::string& what,
                                const std::vector<InputPath>& inputs) {
  if (output.empty()) return;
  if (!IsValidUtf8(output.string())) {
    ThrowInputError(output, 0, "{}: the path is not valid UTF-8 (hmc records paths in JSON "
                    "summaries): choose a UTF-8 name", what);
  }
  const fs::path out = Resolved(output);
  std::error_code ec;
  for (const InputPath& in : inputs) {
    if (in.path.empty()) continue;
    if (!IsValidUtf8(in.path.string())) {
      ThrowInputError(in.path, 0, "{}: the path is not valid UTF-8 (hmc records paths in JSON "
                      "summaries): rename it", in.flag);
    }
    if (out == Resolved(in.path)) {
      ThrowInputError(output, 0, "{}: is also the input {}: refusing to overwrite an input",
                      what, in.flag);
    }
  }
  for (const InputPath& in : inputs) {
    if (in.path.empty()) continue;
    const fs::path input = Resolved(in.path);
    if (fs::is_directory(input, ec) && IsWithin(out, input)) {
      ThrowInputError(output, 0, "{}: lies inside the input folder {} ({}): refusing to write "
                      "into an input", what, in.flag, in.path.string());
    }
    if (IsWithin(input, out)) {
      ThrowInputError(output, 0, "{}: holds the input {} ({}): refusing to write over an input",
                      what, in.flag, in.path.string());
    }
  }
}

void PrepareOutputPath(const fs::path& path, const std::string& what, bool folder,
                       const std::vector<InputPath>& inputs) {
  if (path.empty()) ThrowInputError(path, 0, "{}: an empty path", what);
  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);
  if (!folder && fs::is_directory(status)) {
    ThrowInputError(path, 0, "{}: is a folder, not a file to write", what);
  }
  if (folder && fs::exists(status) && !fs::is_directory(status)) {
    ThrowInputError(path, 0, "{}: exists and is not a folder", what);
  }
  const fs::path dir = path.has_parent_path() ? path.parent_path() : ".";
  const fs::path package = EnclosingActorPackage(dir);
  if (!package.empty()) {
    ThrowInputError(path, 0, "{}: refusing to write inside the actor package {}", what,
                    package.string());
  }
  CheckOutputApartFromInputs(path, what, inputs);
  std::error_code error;
  fs::create_directories(dir, error);
  if (error) {
    ThrowInputError(path, 0, "{}: cannot create its folder {}: {}", what, dir.string(),
                    error.message());
  }
  if (::access(dir.c_str(), W_OK | X_OK) != 0) {
    ThrowInputError(path, 0, "{}: folder {} cannot be written: {}", what, dir.string(),
                    std::strerror(errno));
  }
}

fs::path EnclosingActorPackage(const fs::path& path) {
  std::error_code ec;
  fs::path p = fs::weakly_canonical(fs::absolute(path, ec), ec);
  if (ec) return {};
  for (; !p.empty(); p = p.parent_path()) {
    if (fs::is_regular_file(p / "actor.yaml", ec)) return p;
    if (p == p.parent_path()) break;
  }
  return {};
}

namespace {

constexpr const char* kOutputMark = ".hmc_output";

// Removes `.NAME.tmp.PID.N` / `.NAME.old.PID.N` folders of killed runs.
void RemoveStaleFolders(const fs::path& parent, const std::string& name) {
  std::error_code ec;
  for (fs::directory_iterator it(parent, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string file = it->path().filename().string();
    for (const std::string kind : {".tmp.", ".old."}) {
      const std::string prefix = "." + name + kind;
      if (file.compare(0, prefix.size(), prefix) != 0) continue;
      const long pid = std::strtol(file.c_str() + prefix.size(), nullptr, 10);
      if (pid <= 0 || pid == getpid()) continue;
      if (::kill(static_cast<pid_t>(pid), 0) == 0 || errno != ESRCH) continue;
      std::error_code ignored;
      fs::remove_all(it->path(), ignored);
    }
  }
}

}  // namespace

void WriteFolderAtomic(const fs::path& dir_in, const std::string& what,
                       const std::function<void(const fs::path&)>& write) {
  static std::atomic<int> counter{0};
  fs::path dir = dir_in;
  if (dir.filename().empty()) dir = dir.parent_path();  // "out/"
  PrepareOutputPath(dir, what, true);
  std::error_code ec;
  const bool exists = fs::exists(dir, ec);
  if (exists && !fs::is_empty(dir, ec) &&
      !(fs::is_regular_file(dir / kOutputMark, ec) && ReadFile(dir / kOutputMark) == what + "\n")) {
    ThrowInputError(dir, 0,
                    "{}: refusing to replace a folder that is not empty and was not written "
                    "by {} (remove it, or choose another --out)",
                    what, what);
  }
  const fs::path parent = dir.has_parent_path() ? dir.parent_path() : ".";
  const std::string name = dir.filename().string();
  RemoveStaleFolders(parent, name);
  const int n = counter++;
  const fs::path temp = parent / fmt::format(".{}.tmp.{}.{}", name, getpid(), n);
  const fs::path old = parent / fmt::format(".{}.old.{}.{}", name, getpid(), n);
  fs::remove_all(temp, ec);
  EnsureDirectory(temp);
  try {
    write(temp);
    WriteFileAtomic(temp / kOutputMark, what + "\n");
    std::error_code error;
    if (exists) {
      fs::rename(dir, old, error);
      if (error) ThrowInputError(dir, 0, "cannot move the previous folder aside: {}", error.message());
    }
    fs::rename(temp, dir, error);
    if (error) {
      std::error_code ignored;
      if (exists) fs::rename(old, dir, ignored);
      ThrowInputError(dir, 0, "cannot rename the temporary folder: {}", error.message());
    }
    SyncPath(parent, true);
    if (exists) fs::remove_all(old, ec);
  } catch (...) {
    std::error_code ignored;
    fs::remove_all(temp, ignored);
    throw;
  }
}

}  // namespace hmc
