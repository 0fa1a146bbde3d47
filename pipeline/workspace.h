// The shot workspace of `hmc run --out WORK` (docs/formats.md, "Shot
// workspace"): one folder per stage, `WORK/<stage>/`, holding the files the
// stage's own command writes, its `options_used.yaml`, and `summary.json`,
// written last.
//
// Resume follows Meshroom/AliceVision's node cache: a stage is complete when
// its summary exists and records the same key -- the content hashes of its
// inputs and of its options -- as the run about to start; a complete stage
// is not redone. A stage is (re)done in a fresh `WORK/.<stage>.partial/`
// that replaces `WORK/<stage>/` only once its summary is written, so a run
// killed at any point leaves either the old complete folder or a partial
// one that the next run removes: never a half-written stage folder that
// looks complete, and no stale temporary files.
//
// A stage's summary also records its outputs: every file the stage wrote,
// by relative path, with its content hash. A stage is complete only while
// those files are there unchanged (a deleted mesh.pc2 is made again), and
// they are the only files hmc run may replace: a workspace holding files
// it did not write (notes in WORK/track/, a PDF in WORK/report/, a folder
// of someone else's) is refused before any work, never emptied. One run at
// a time: the workspace is locked (WORK/.hmc_lock, flock) while a
// Workspace object lives. docs/reliability.md.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace hmc {

// What a stage's result depends on. Two keys are equal when every input
// hash and the options hash are equal.
struct StageKey {
  std::string stage;                          // folder name ("track")
  std::map<std::string, std::string> inputs;  // input label -> content hash (hex)
  std::string options;                        // hash (hex) of the options text

  // Adds the content hash of `path` (a file, or a folder: every file in it
  // by relative path) under `label`. Throws InputError if it cannot be read.
  void AddInput(const std::string& label, const std::filesystem::path& path);
  void AddInputText(const std::string& label, const std::string& text);

  nlohmann::json ToJson() const;
  bool operator==(const StageKey& other) const {
    return stage == other.stage && inputs == other.inputs && options == other.options;
  }
};

// The content hash of a file, or of a folder's files (sorted relative paths
// and their contents; hidden files ignored).
uint64_t HashPath(const std::filesystem::path& path);

class Workspace {
 public:
  // Creates `root` or claims an existing one: takes its lock (InputError
  // "WORK is in use by pid N" while another process holds it) and refuses
  // (InputError listing them) files in it that hmc run did not write:
  // files in a stage folder its summary does not list as outputs, a stage
  // folder without a summary, and -- unless the folder is already marked a
  // workspace (WORK/.hmc_workspace) -- anything else. Then marks it.
  // `stages`: the stage folder names (PipelineStages()).
  Workspace(std::filesystem::path root, const std::vector<std::string>& stages);
  ~Workspace();
  Workspace(const Workspace&) = delete;
  Workspace& operator=(const Workspace&) = delete;

  const std::filesystem::path& root() const { return root_; }
  std::filesystem::path StageDir(const std::string& stage) const { return root_ / stage; }

  // True if WORK/<stage>/summary.json exists, parses, records `key`, and
  // every output it lists is there with the content it recorded.
  bool IsComplete(const StageKey& key) const;
  // The stage's summary.json (null if missing or unreadable).
  nlohmann::json ReadSummary(const std::string& stage) const;

  // Runs body(dir) with a fresh, empty WORK/.<stage>.partial/ and returns
  // what it returns; `body` writes the stage's files there and returns the
  // stage's own report. Then writes summary.json ({"stage", "key",
  // "seconds", "report", "outputs": {relative path: content hash}}; a
  // summary.json the stage's command wrote itself
  // goes into the report as "command_summary") last, atomically, and moves
  // the folder to
  // WORK/<stage>/, replacing the old one. If `body` throws, the partial
  // folder is removed and WORK/<stage>/ is left as it was.
  nlohmann::json RunStage(const StageKey& key,
                          const std::function<nlohmann::json(const std::filesystem::path&)>& body);

  // Removes WORK/<stage>/ (to force a redo) and any partial folder.
  void Invalidate(const std::string& stage) const;

  // Throws InputError naming WORK unless WORK is still the folder this
  // object claimed (its lock file the one held open). A workspace on a
  // share or drive that goes away leaves an empty local folder at its
  // path, where the stage's command would recreate its folders and a
  // stage would be written "complete" (issue 45, second campaign). Called
  // before each stage and by RunStage before and after the stage's work.
  void CheckStillThere() const;

 private:
  std::filesystem::path root_;
  int lock_fd_ = -1;
};

}  // namespace hmc
