// `hmc batch`: a shoot day of takes (docs/farm.md). Each take is one `hmc
// run` workspace, DAY/<take>/, run by the per-take command
//
//   hmc batch --out DAY --take NAME
//
// which reads the day's plan (DAY/.batch/plan.json: the takes, the actor,
// the run config), runs `hmc run` in-process on the take and records its
// state in DAY/.batch/takes/<take>.json. The local scheduler starts that
// command as child processes, up to --jobs at a time; the SLURM scheduler
// (pipeline/batch_slurm.h) submits it as a job array. Only files pass
// between them. DAY/batch.json and the day report DAY/report.html are
// assembled from the plan, the take states and the workspaces
// (docs/formats.md, "Shoot day").
#pragma once

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/options.h"

namespace hmc {

// The batch's own options (`batch:` of the --config; the other sections
// are the run config every take gets).
struct BatchOptions {
  std::string scheduler = "local";  // local | slurm
  int jobs = 0;                     // takes at a time with the local scheduler (0 = the cores)
  std::string slurm_partition;      // sbatch --partition ("" = the cluster's default)
  std::string slurm_time;           // sbatch --time per task ("" = the partition's default)
  std::string slurm_mem;            // sbatch --mem per task ("" = the cluster's default; docs/farm.md measures a take)
  int slurm_cpus = 1;               // sbatch --cpus-per-task (cores per take)
  std::string slurm_account;        // sbatch --account ("" = none)
  std::vector<std::string> slurm_extra;  // more sbatch arguments, given to every job ("--qos=low")
  int chunk_frames = 0;   // a take longer than this is tracked in chunks of this many frames, run as tasks of their own (0 = one task per take)
  int chunk_overlap = 30; // frames each chunk also tracks before its own, so that its labels are settled (docs/farm.md)

  void Register(OptionFields* fields);
  bool Check() const;
};

// One take of the day.
struct Take {
  std::string name;         // DAY/<name>/; letters, digits, '_', '-', '.' (not first); not logs, batch.json, report.html
  std::string shot;         // shot folder (footage)
  std::string frames;       // frame range "A:B" ("" = the run config's, else all)
  std::string calibration;  // the take's calibration ("" = --calibration)
  // Its frame chunks (hmc batch --chunk-frames): each chunk's own frames,
  // inclusive, in order (empty: the take is one task).
  std::vector<std::pair<int, int>> chunks;
};

// The takes of --takes: a folder (its sub-folders holding footage,
// cam0/cam1 videos or image folders, sorted by name; a sub-folder with one
// camera is a take, and fails with the missing one named), or a list:
// a .yaml/.yml file (`takes:` sequence of {name, shot, frames,
// calibration}) or a .csv file (header `name,shot,frames,calibration`;
// frames and calibration may be left out or empty). Relative paths are
// relative to the list's folder. Throws InputError naming the file and
// line for a bad list, a duplicate or invalid name, a missing shot folder.
std::vector<Take> ReadTakes(const std::filesystem::path& takes);

// What the per-take command needs: DAY/.batch/plan.json.
struct BatchPlan {
  std::string actor;        // absolute
  std::string calibration;  // absolute (--calibration)
  std::string run_config;   // DAY/.batch/run.yaml ("" = defaults)
  std::vector<Take> takes;  // paths absolute
  int chunk_overlap = 0;    // frames a chunk tracks before its own (BatchOptions)
  const Take* Find(const std::string& name) const;
};

// Splits each take of `plan` longer than `chunk_frames` frames into chunks
// of that many frames (Take::chunks; the last may be shorter); 0 leaves
// every take one task. The take's frames are its footage's, within its
// frame range (the take's, else the run config's `run.frames`). A take
// whose footage cannot be opened is left one task: its run fails with the
// reason.
void PlanChunks(BatchPlan* plan, int chunk_frames, int chunk_overlap);

// What the batch runs, by name ("units"): a take NAME is the unit NAME
// (its hmc run; for a chunked take, on the tracks of its chunks); a chunked
// take also has NAME@calibrate (its first pass: hmc run --to calibrate,
// the tag calibration from the whole take, which its chunks then use as it
// is) and NAME@chunkK (chunk K's hmc run --to track on its frames and the
// overlap before them, in DAY/.batch/chunks/NAME/K/). In order: a unit
// runs after those before it of its take (NAME@calibrate, then the chunks
// in any order, then NAME).
std::vector<std::string> TakeUnits(const Take& take);
// The take of a unit name, and its part: "" (the take), "calibrate", "chunkK".
std::pair<std::string, std::string> SplitUnit(const std::string& unit);
// The units `unit` waits for (the ones before it of its take, per the
// order above).
std::vector<std::string> UnitDependencies(const BatchPlan& plan, const std::string& unit);
void WritePlan(const std::filesystem::path& day, const BatchPlan& plan);
BatchPlan ReadPlan(const std::filesystem::path& day);

// Writes DAY/.batch/run.yaml: `config` without its `batch:` section, or
// nothing for an empty `config`; returns its path ("" = none). When its
// `solve:` section sets index options (`index:`, `nn:`), also writes them
// as DAY/.batch/index.yaml, the config of the day's `hmc index`.
std::string WriteRunConfig(const std::filesystem::path& day, const std::string& config);

// The `hmc index` command line (without the program name) that builds the
// index every take's solve loads: the actor, and DAY/.batch/index.yaml if
// there is one.
std::vector<std::string> IndexArgs(const std::filesystem::path& day, const BatchPlan& plan);

// The index cache every take of DAY reads (XDG_CACHE_HOME of the takes and
// of the index job): DAY/.batch/cache.
std::filesystem::path DayIndexCache(const std::filesystem::path& day);

// The `hmc run` command line of `take` (without the program name).
std::vector<std::string> TakeRunArgs(const std::filesystem::path& day, const BatchPlan& plan,
                                     const Take& take);
// The `hmc run` command line of a unit (TakeUnits). Throws InputError for
// a unit the day does not have.
std::vector<std::string> UnitRunArgs(const std::filesystem::path& day, const BatchPlan& plan,
                                     const std::string& unit);

// DAY/logs/<take>.log: what the take's process printed.
std::filesystem::path TakeLog(const std::filesystem::path& day, const std::string& take);

// A take's state file, DAY/.batch/takes/<take>.json: {"state": "running" |
// "done" | "failed", "reason", "args", "started", "finished", "seconds"}
// (null when the take never started).
nlohmann::json ReadTakeState(const std::filesystem::path& day, const std::string& take);

// True when the take finished ("done") with the command line it would run
// now, its inputs unchanged (the run config's and the calibration's
// contents; the shot's and the actor's files by size and time) and its
// workspace there: the batch skips it (its hmc run would find every stage
// complete).
bool TakeIsComplete(const std::filesystem::path& day, const BatchPlan& plan, const Take& take);
// The same for one unit (TakeUnits).
bool UnitIsComplete(const std::filesystem::path& day, const BatchPlan& plan,
                    const std::string& unit);

// The per-take command: runs `hmc run` on the take (or unit, TakeUnits)
// with `run_command`
// (apps/command.h RunCommandLine), recording its state before and after;
// a take that throws is "failed" with the message as its reason. Returns 0
// when done, 1 when failed.
using BatchCommandRunner = std::function<int(const std::vector<std::string>& args)>;
int RunTake(const std::filesystem::path& day, const BatchPlan& plan, const std::string& take,
            const BatchCommandRunner& run_command);

// batch.json's content: per take its state, reason, log, times, summary
// figures, warnings, report and thumbnail paths (relative to DAY), and the
// counts. States: pending (never started), queued (`queue_state(take)`,
// squeue's state, is not empty), running, done, failed, incomplete (its
// state says running but its process is gone: killed or cancelled).
nlohmann::json CollectBatch(const std::filesystem::path& day, const std::string& scheduler,
                            const std::function<std::string(const std::string&)>& queue_state);

// Writes DAY/batch.json and DAY/report.html (the day report: every take
// with its state, reason, figures, warnings, a thumbnail and a link to
// its own report) from CollectBatch's `batch`.
void WriteDayFiles(const std::filesystem::path& day, const nlohmann::json& batch);

// A one-line-per-take table of `batch` for the terminal (--status).
std::string StatusTable(const nlohmann::json& batch);

// The local scheduler: runs every take that is not complete, up to `jobs`
// at a time, as `hmc_binary batch --out DAY --take NAME` child processes
// with the day's index cache, after building the actor's index once
// (`hmc index`); then writes batch.json and the day report. Returns the
// number of failed takes.
int RunLocalBatch(const std::filesystem::path& day, const BatchPlan& plan, int jobs,
                  const std::filesystem::path& hmc_binary);

}  // namespace hmc
