#include "pipeline/workspace.h"

#include <algorithm>
#include <chrono>
#include <system_error>
#include <vector>

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

Workspace::Workspace(fs::path root) : root_(std::move(root)) { EnsureDirectory(root_); }

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
  if (!summary.is_object() || !summary.contains("key")) return false;
  return summary["key"] == key.ToJson();
}

void Workspace::Invalidate(const std::string& stage) const {
  std::error_code ec;
  fs::remove_all(StageDir(stage), ec);
  fs::remove_all(root_ / ("." + stage + ".partial"), ec);
  if (ec) ThrowInputError(StageDir(stage), 0, "cannot remove: {}", ec.message());
}

nlohmann::json Workspace::RunStage(
    const StageKey& key, const std::function<nlohmann::json(const fs::path&)>& body) {
  const fs::path partial = root_ / ("." + key.stage + ".partial");
  const fs::path final_dir = StageDir(key.stage);
  std::error_code ec;
  fs::remove_all(partial, ec);  // a killed earlier run's leftovers
  EnsureDirectory(partial);
  nlohmann::json report;
  const auto start = std::chrono::steady_clock::now();
  try {
    report = body(partial);
    if (!report.is_object()) report = nlohmann::json{{"value", report}};
  } catch (...) {
    fs::remove_all(partial, ec);
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
  const nlohmann::json summary = {{"stage", key.stage},
                                  {"key", key.ToJson()},
                                  {"seconds", seconds},
                                  {"report", report}};
  WriteFileAtomic(partial / "summary.json", summary.dump(1) + "\n");
  // Swap: a kill between the two steps leaves no WORK/<stage>/ (redone next
  // time) and the complete partial folder (removed next time).
  fs::remove_all(final_dir, ec);
  if (ec) ThrowInputError(final_dir, 0, "cannot replace the stage folder: {}", ec.message());
  fs::rename(partial, final_dir, ec);
  if (ec) ThrowInputError(final_dir, 0, "cannot move the finished stage into place: {}", ec.message());
  return summary;
}

}  // namespace hmc
