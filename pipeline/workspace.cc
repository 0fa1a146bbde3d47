#include "pipeline/workspace.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <system_error>
#include <vector>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <spdlog/spdlog.h>

#include "core/error.h"
#include "core/file_util.h"
#include "core/hash.h"

namespace hmc {

namespace fs = std::filesystem;

uint64_t HashPath(const fs::path& path) {
  std::error_code ec;
  if (!fs::is_directory(path, ec)) return HashFile(path);
  std::vector<fs::path> files;
  for (fs::recursive_directory_iterator it(path, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (!name.empty() && name.front() == '.') {
      if (it->is_directory(ec)) it.disable_recursion_pending();
      continue;
    }
    if (it->is_regular_file(ec)) files.push_back(fs::relative(it->path(), path));
  }
  if (ec) ThrowInputError(path, 0, "cannot list the folder to hash it: {}", ec.message());
  std::sort(files.begin(), files.end());
  ContentHasher hasher;
  for (const fs::path& rel : files) {
    const std::string name = rel.generic_string();
    hasher.Update(name);
    hasher.Update(std::string_view("\0", 1));
    hasher.Update(HashHex(HashFile(path / rel)));
  }
  return hasher.Digest();
}

void StageKey::AddInput(const std::string& label, const fs::path& path) {
  inputs[label] = HashHex(HashPath(path));
}

void StageKey::AddInputText(const std::string& label, const std::string& text) {
  inputs[label] = HashHex(HashBytes(text));
}

nlohmann::json StageKey::ToJson() const {
  return {{"stage", stage}, {"inputs", inputs}, {"options", options}};
}

namespace {

constexpr const char* kMark = ".hmc_workspace";
constexpr const char* kLock = ".hmc_lock";

// `.NAME.tmp.PID.N`: a temporary of WriteFileAtomic (core/file_util.h).
bool IsTemporary(const std::string& name) {
  return !name.empty() && name.front() == '.' && name.find(".tmp.") != std::string::npos;
}

// What a file browser leaves in any folder it shows (macOS Finder's
// .DS_Store and AppleDouble `._*` files, Windows Explorer's Thumbs.db):
// not the user's work, replaced with the stage folder like its outputs.
bool IsBrowserClutter(const std::string& name) {
  return name == ".DS_Store" || name.rfind("._", 0) == 0 || name == "Thumbs.db" ||
         name == "desktop.ini";
}

// Every regular file under `dir` by relative path (hidden ones too).
std::vector<std::string> FilesUnder(const fs::path& dir) {
  std::vector<std::string> files;
  std::error_code ec;
  for (fs::recursive_directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    if (!it->is_directory(ec)) files.push_back(fs::relative(it->path(), dir).generic_string());
  }
  if (ec) ThrowInputError(dir, 0, "cannot list the folder: {}", ec.message());
  std::sort(files.begin(), files.end());
  return files;
}

// The files of a stage folder that hmc run did not write (relative to the
// workspace): all but summary.json and the outputs it lists (a summary of
// an earlier version, without "outputs", owns its whole folder).
std::vector<std::string> ForeignFiles(const fs::path& root, const std::string& stage) {
  const fs::path dir = root / stage;
  nlohmann::json summary;
  try {
    summary = nlohmann::json::parse(ReadFile(dir / "summary.json"));
  } catch (const std::exception&) {
    summary = nullptr;
  }
  std::vector<std::string> foreign;
  const bool owns_all = summary.is_object() && summary.value("stage", "") == stage &&
                        !summary.contains("outputs");
  for (const std::string& file : FilesUnder(dir)) {
    const std::string name = fs::path(file).filename().string();
    if (owns_all || IsTemporary(name) || IsBrowserClutter(name)) continue;
    if (summary.is_object() && (file == "summary.json" || summary["outputs"].contains(file))) {
      continue;
    }
    foreign.push_back(stage + "/" + file);
  }
  return foreign;
}

}  // namespace

Workspace::Workspace(fs::path root, const std::vector<std::string>& stages)
    : root_(std::move(root)) {
  const auto is_stage = [&stages](const std::string& name) {
    return std::find(stages.begin(), stages.end(), name) != stages.end();
  };
  EnsureDirectory(root_);
  lock_fd_ = ::open((root_ / kLock).c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (lock_fd_ < 0) {
    ThrowInputError(root_ / kLock, 0, "cannot open the workspace's lock: {}", std::strerror(errno));
  }
  if (::flock(lock_fd_, LOCK_EX | LOCK_NB) != 0) {
    std::string pid = ReadFile(root_ / kLock);
    while (!pid.empty() && std::isspace(static_cast<unsigned char>(pid.back()))) pid.pop_back();
    ::close(lock_fd_);
    lock_fd_ = -1;
    ThrowInputError(root_, 0, "is in use by pid {} (another hmc run): wait for it, or choose "
                    "another --out", pid.empty() ? "?" : pid);
  }
  const std::string pid = std::to_string(::getpid()) + "\n";
  if (::ftruncate(lock_fd_, 0) != 0 || ::write(lock_fd_, pid.data(), pid.size()) < 0) {
    spdlog::debug("{}: cannot record the pid", (root_ / kLock).string());
  }
  try {
    std::error_code ec;
    const bool marked = fs::is_regular_file(root_ / kMark, ec);
    std::vector<std::string> foreign;
    for (fs::directory_iterator it(root_, ec), end; !ec && it != end; it.increment(ec)) {
      const std::string name = it->path().filename().string();
      if (name == kMark || name == kLock) continue;
      // A run killed while it wrote the mark leaves the mark's temporary
      // (`..hmc_workspace.tmp.PID.N`) and no mark: hmc's own, removed when
      // the mark is written below.
      if (name.rfind(std::string(".") + kMark + ".tmp.", 0) == 0) continue;
      if (name.front() == '.' && name.size() > 9 && name.compare(name.size() - 8, 8, ".partial") == 0 &&
          is_stage(name.substr(1, name.size() - 9))) {
        continue;  // a killed run's partial stage: removed when the stage runs
      }
      if (is_stage(name) && it->is_directory(ec)) {
        const std::vector<std::string> files = ForeignFiles(root_, name);
        foreign.insert(foreign.end(), files.begin(), files.end());
      } else if (!marked && !IsBrowserClutter(name)) {
        foreign.push_back(name);  // never touched, but not a workspace
      }
    }
    if (ec) ThrowInputError(root_, 0, "cannot list the workspace: {}", ec.message());
    if (!foreign.empty()) {
      const size_t shown = std::min<size_t>(foreign.size(), 5);
      ThrowInputError(root_, 0,
                      "holds {} file(s) hmc run did not write ({}{}): hmc run replaces only its "
                      "own files; move them, or choose another --out",
                      foreign.size(),
                      fmt::format("{}", fmt::join(foreign.begin(), foreign.begin() + shown, ", ")),
                      foreign.size() > shown ? ", ..." : "");
    }
    if (!marked) WriteFileAtomic(root_ / kMark, "hmc run workspace (docs/formats.md)\n");
  } catch (...) {
    ::close(lock_fd_);
    lock_fd_ = -1;
    throw;
  }
}

Workspace::~Workspace() {
  if (lock_fd_ < 0) return;
  // Emptied before it is released, so a finished workspace's files do not
  // depend on the pid that wrote them.
  if (::ftruncate(lock_fd_, 0) != 0) spdlog::debug("{}: cannot empty the lock", root_.string());
  ::close(lock_fd_);
}

nlohmann::json Workspace::ReadSummary(const std::string& stage) const {
  const fs::path file = StageDir(stage) / "summary.json";
  std::error_code ec;
  if (!fs::is_regular_file(file, ec)) return nullptr;
  try {
    return nlohmann::json::parse(ReadFile(file));
  } catch (const std::exception& e) {
    spdlog::warn("{}: unreadable summary ({}): the stage will be redone", file.string(), e.what());
    return nullptr;
  }
}

bool Workspace::IsComplete(const StageKey& key) const {
  const nlohmann::json summary = ReadSummary(key.stage);
  if (!summary.is_object() || !summary.contains("key") || summary["key"] != key.ToJson()) {
    return false;
  }
  if (!summary.contains("outputs") || !summary["outputs"].is_object()) return false;
  for (const auto& [file, hash] : summary["outputs"].items()) {
    const fs::path path = StageDir(key.stage) / file;
    std::error_code ec;
    if (!fs::is_regular_file(path, ec)) {
      spdlog::warn("run: {} is missing: the {} stage is redone", path.string(), key.stage);
      return false;
    }
    if (hash != HashHex(HashFile(path))) {
      spdlog::warn("run: {} changed since the {} stage wrote it: the stage is redone",
                   path.string(), key.stage);
      return false;
    }
  }
  return true;
}

void Workspace::Invalidate(const std::string& stage) const {
  std::error_code ec;
  fs::remove_all(StageDir(stage), ec);
  fs::remove_all(root_ / ("." + stage + ".partial"), ec);
  if (ec) ThrowInputError(StageDir(stage), 0, "cannot remove: {}", ec.message());
}

void Workspace::CheckStillThere() const {
  struct stat held {}, now {};
  const bool same = ::fstat(lock_fd_, &held) == 0 && ::stat((root_ / kLock).c_str(), &now) == 0 &&
                    held.st_dev == now.st_dev && held.st_ino == now.st_ino;
  if (!same) {
    ThrowInputError(root_, 0,
                    "the workspace disappeared during the run (a network share or drive that "
                    "went away, or the folder moved): nothing more is written; the stages "
                    "completed before are kept there -- run again once it is back");
  }
}

nlohmann::json Workspace::RunStage(
    const StageKey& key, const std::function<nlohmann::json(const fs::path&)>& body) {
  const fs::path partial = root_ / ("." + key.stage + ".partial");
  const fs::path final_dir = StageDir(key.stage);
  std::error_code ec;
  CheckStillThere();
  fs::remove_all(partial, ec);  // a killed earlier run's leftovers
  EnsureDirectory(partial);
  nlohmann::json report;
  const auto start = std::chrono::steady_clock::now();
  try {
    report = body(partial);
    if (!report.is_object()) report = nlohmann::json{{"value", report}};
    // The stage's command recreates a folder that went away: what it wrote
    // then is not in the workspace.
    CheckStillThere();
  } catch (...) {
    fs::remove_all(partial, ec);
    CheckStillThere();  // "cannot write" from a command: say why
    throw;
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  // A command that writes its own summary.json (a stage run alone does)
  // has it kept as the stage's report.
  const fs::path own = partial / "summary.json";
  if (fs::is_regular_file(own, ec)) {
    try {
      report["command_summary"] = nlohmann::json::parse(ReadFile(own));
    } catch (const std::exception& e) {
      spdlog::warn("{}: unreadable ({})", own.string(), e.what());
    }
  }
  // The stage's outputs and their hashes: what it owns, and what must be
  // there unchanged for it to stay complete.
  nlohmann::json outputs = nlohmann::json::object();
  for (const std::string& file : FilesUnder(partial)) {
    if (file == "summary.json") continue;
    if (IsTemporary(fs::path(file).filename().string())) {
      fs::remove(partial / file, ec);  // never part of a complete stage
      continue;
    }
    outputs[file] = HashHex(HashFile(partial / file));
  }
  const nlohmann::json summary = {{"stage", key.stage},
                                  {"key", key.ToJson()},
                                  {"seconds", seconds},
                                  {"report", report},
                                  {"outputs", outputs}};
  WriteFileAtomic(partial / "summary.json", summary.dump(1) + "\n");
  try {
    CheckStillThere();
  } catch (...) {
    fs::remove_all(partial, ec);
    throw;
  }
  // Swap: a kill between the two steps leaves no WORK/<stage>/ (redone next
  // time) and the complete partial folder (removed next time).
  fs::remove_all(final_dir, ec);
  if (ec) ThrowInputError(final_dir, 0, "cannot replace the stage folder: {}", ec.message());
  fs::rename(partial, final_dir, ec);
  if (ec) ThrowInputError(final_dir, 0, "cannot move the finished stage into place: {}", ec.message());
  return summary;
}

}  // namespace hmc
