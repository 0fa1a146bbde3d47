// `hmc batch --scheduler slurm` (docs/farm.md): the day submitted to a real
// SLURM with sbatch. Three jobs, files only between them:
//   1. hmc-index: `hmc index --actor A` (IndexArgs) into the day's index cache;
//   2. hmc-take: a job array, one task per take still to do (the array
//      index is the take's line in DAY/.batch/takes.txt), each running
//      the per-take command `hmc batch --out DAY --take NAME`, after 1
//      (afterany: a failed index only costs each take its own build);
//      with chunked takes (--chunk-frames), their first passes are an
//      array hmc-first before it, its tasks also run their chunks
//      (NAME@chunkK), and their merging runs are an array hmc-merge after
//      it (pipeline/batch.h, TakeUnits);
//   3. hmc-report: `hmc batch --out DAY --day_report`, after 2 (afterany,
//      so the day report lists the failed takes too).
// The job scripts are written to DAY/.batch/slurm/ (a facility can read
// them, or call the per-take command from its own submitter); the job ids
// to DAY/.batch/slurm.json. Rerunning the same command submits only the
// takes that are not complete.
#pragma once

#include <filesystem>
#include <map>
#include <string>

#include "pipeline/batch.h"

namespace hmc {

struct SlurmJobs {
  std::string index, array, report;     // job ids ("" = none submitted)
  // With chunked takes (--chunk-frames): the array of their first passes
  // (NAME@calibrate), before `array` (which then also runs their chunks),
  // and the array of their merging runs (NAME), after it.
  std::string first, merge;
  std::map<std::string, int> tasks;     // unit (a take, NAME@calibrate, NAME@chunkK) -> its array index
};

// DAY/.batch/slurm.json, or no jobs.
SlurmJobs ReadSlurmJobs(const std::filesystem::path& day);

// Submits the takes of `plan` that are not complete (TakeIsComplete);
// with none, only writes the day files. Throws InputError when sbatch is
// missing or refuses a job (with its message), and when jobs of an earlier
// submission of DAY are still in the queue.
SlurmJobs SubmitSlurmBatch(const std::filesystem::path& day, const BatchPlan& plan,
                           const BatchOptions& options, const std::filesystem::path& hmc_binary);

// squeue's state of every queued task of the arrays, by unit and by take
// ("PENDING", "RUNNING", ...: a take has the state of one of its queued
// units); units and takes not in the queue are absent.
std::map<std::string, std::string> SlurmTakeQueue(const SlurmJobs& jobs);

// Blocks until no job of `jobs` is in squeue.
void WaitSlurmJobs(const SlurmJobs& jobs);

// The jobs and squeue's lines for them, for --status ("" without jobs).
std::string SlurmQueueText(const SlurmJobs& jobs);

}  // namespace hmc
