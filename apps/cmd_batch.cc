// `hmc batch --takes DIR_OR_LIST --actor DIR --calibration CAL --out DAY
// [--scheduler local|slurm] [--jobs N] [--chunk-frames N] [--config FILE]`: a shoot day of
// takes, one `hmc run` workspace per take under DAY/<take>/, on this
// machine or as SLURM jobs (pipeline/batch.h, pipeline/batch_slurm.h,
// docs/farm.md). Also `hmc batch --status DAY`, `--wait`, and the per-take
// command a farm runs, `hmc batch --out DAY --take NAME`.
#include <sys/file.h>

#include <cstdio>
#include <cstdlib>
#include <map>
#include <memory>
#include <string>

#include <fcntl.h>
#include <unistd.h>

#include <spdlog/spdlog.h>

#include "apps/command.h"
#include "core/file_util.h"
#include "core/logging.h"
#include "pipeline/batch.h"
#include "pipeline/batch_slurm.h"
#include "pipeline/subprocess.h"

namespace hmc {
namespace {

namespace fs = std::filesystem;

struct BatchCommand {
  std::string takes, actor, calibration, out, status, take;
  bool wait = false;
  bool day_report = false;
  bool plan = false;
  BatchOptions options;
};

// One submitting or scheduling batch per day at a time (DAY/.batch/lock);
// the per-take commands lock their own workspaces.
class DayLock {
 public:
  explicit DayLock(const fs::path& day) {
    EnsureDirectory(day / ".batch");
    const fs::path file = day / ".batch" / "lock";
    fd_ = open(file.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (fd_ < 0 || flock(fd_, LOCK_EX | LOCK_NB) != 0) {
      throw InputError(day.string() + ": another hmc batch is scheduling this day");
    }
  }
  ~DayLock() {
    if (fd_ >= 0) close(fd_);
  }

 private:
  int fd_ = -1;
};

int Status(const fs::path& day, bool wait) {
  const SlurmJobs jobs = ReadSlurmJobs(day);
  if (wait) WaitSlurmJobs(jobs);
  const std::string scheduler = jobs.index.empty() ? "local" : "slurm";
  const std::map<std::string, std::string> queue = SlurmTakeQueue(jobs);
  const nlohmann::json batch = CollectBatch(day, scheduler, [&](const std::string& take) {
    const auto it = queue.find(take);
    return it == queue.end() ? std::string() : it->second;
  });
  // The jobs have ended: batch.json and the day report as they stand now
  // (the report job's run may have been cancelled, or preceded a task's
  // end).
  if (wait && !jobs.index.empty()) WriteDayFiles(day, batch);
  std::fputs(StatusTable(batch).c_str(), stdout);
  std::fputs(SlurmQueueText(jobs).c_str(), stdout);
  int failed = 0;
  for (const auto& t : batch["takes"]) failed += t["state"] != "done";
  return failed == 0 ? 0 : 1;
}

}  // namespace

HMC_COMMAND(Batch, "", "batch",
            "A shoot day of takes: one hmc run workspace per take, locally or as SLURM jobs, "
            "with batch.json and a day report") {
  auto cmd = std::make_shared<BatchCommand>();
  const std::string data = "The day (required to start or resume one)";
  app->add_option("--takes", cmd->takes,
                  "Folder whose sub-folders hold the takes' footage, or a .yaml/.csv list of "
                  "takes (name, shot, frames, calibration)")
      ->group(data);
  app->add_option("--actor", cmd->actor, "Actor package folder, shared by every take")->group(data);
  app->add_option("--calibration", cmd->calibration,
                  "calibration.yaml of the rig (a take's own in the list overrides it)")
      ->group(data);
  app->add_option("--out", cmd->out, "Day folder DAY: DAY/<take>/, DAY/batch.json, "
                                     "DAY/report.html")
      ->group(data);
  const std::string other = "Watching a day, and the commands the jobs run";
  app->add_option("--status", cmd->status,
                  "Print the state of day DAY (workspaces, squeue) and exit 0 when every take is done")
      ->group(other);
  app->add_flag("--wait", cmd->wait,
                "Block until the day's SLURM jobs have ended (with --status DAY, or after "
                "submitting); exit 0 when every take is done")
      ->group(other);
  app->add_option("--take", cmd->take,
                  "With --out DAY: run that one take of the day (what each job runs), or one "
                  "part of a chunked take: NAME@calibrate, NAME@chunkK")
      ->group(other);
  app->add_flag("--day_report", cmd->day_report,
                "With --out DAY: write batch.json and report.html from the workspaces (the "
                "last SLURM job)")
      ->group(other);
  app->add_flag("--plan", cmd->plan,
                "Write the day's plan and print the command of each take still to do, one per "
                "line, without running them: for a farm's own submitter (docs/farm.md)")
      ->group(other);
  OptionFields fields;
  cmd->options.Register(&fields);
  // --config: `batch:` holds these options; every other section is the
  // run config each take's hmc run gets (configs/run.yaml).
  auto binding = std::make_shared<OptionBinding>(app, std::move(fields), "batch");
  binding->SetCheck([cmd] { return cmd->options.Check(); });
  return [cmd, binding] {
    binding->Apply();
    RequireValid(cmd->options, "batch");
    if (!cmd->status.empty()) return Status(cmd->status, cmd->wait);
    if (cmd->out.empty()) throw InputError("hmc batch: --out DAY is required");
    const fs::path day = fs::absolute(cmd->out).lexically_normal();
    if (!cmd->take.empty()) {
      const BatchPlan plan = ReadPlan(day);
      // The actor's index from the day's cache, whoever started this take.
      setenv("XDG_CACHE_HOME", DayIndexCache(day).c_str(), 1);
      return RunTake(day, plan, cmd->take, &RunCommandLine);
    }
    if (cmd->day_report) {
      WriteDayFiles(day, CollectBatch(day, cmd->options.scheduler,
                                      [](const std::string&) { return std::string(); }));
      return 0;
    }
    for (const auto& [value, flag] : {std::pair{&cmd->takes, "--takes"},
                                      std::pair{&cmd->actor, "--actor"},
                                      std::pair{&cmd->calibration, "--calibration"}}) {
      if (value->empty()) throw InputError(fmt::format("hmc batch: {} is required", flag));
    }
    PrepareOutputPaths({{day, "--out", true}}, {{cmd->takes, "--takes"},
                                                {cmd->actor, "--actor"},
                                                {cmd->calibration, "--calibration"},
                                                {binding->config_file(), "--config"}});
    for (const auto& [path, flag] : {std::pair{cmd->actor, "--actor"},
                                     std::pair{cmd->calibration, "--calibration"}}) {
      std::error_code ec;
      if (!fs::exists(path, ec)) ThrowInputError(path, 0, "{}: does not exist", flag);
    }
    StageTimer timer("batch");
    DayLock lock(day);
    BatchPlan plan;
    plan.actor = fs::absolute(cmd->actor).lexically_normal().string();
    plan.calibration = fs::absolute(cmd->calibration).lexically_normal().string();
    plan.takes = ReadTakes(cmd->takes);
    plan.run_config = WriteRunConfig(day, binding->config_file());
    PlanChunks(&plan, cmd->options.chunk_frames, cmd->options.chunk_overlap);
    WritePlan(day, plan);
    if (cmd->plan) {
      const std::string hmc = SelfExecutable().string();
      std::string index;
      for (const std::string& arg : IndexArgs(day, plan)) index += " '" + arg + "'";
      std::printf("XDG_CACHE_HOME='%s' '%s'%s\n", DayIndexCache(day).c_str(), hmc.c_str(),
                  index.c_str());
      // A chunked take's units in their order: each after the ones
      // before it (UnitDependencies).
      for (const Take& take : plan.takes) {
        if (TakeIsComplete(day, plan, take)) continue;
        for (const std::string& unit : TakeUnits(take)) {
          if (unit != take.name && UnitIsComplete(day, plan, unit)) continue;
          std::printf("'%s' batch --out '%s' --take '%s'\n", hmc.c_str(), day.c_str(),
                      unit.c_str());
        }
      }
      std::printf("'%s' batch --out '%s' --day_report\n", hmc.c_str(), day.c_str());
      return 0;
    }
    if (cmd->options.scheduler == "slurm") {
      SubmitSlurmBatch(day, plan, cmd->options, SelfExecutable());
      return cmd->wait ? Status(day, true) : 0;
    }
    const int failed = RunLocalBatch(day, plan, cmd->options.jobs, SelfExecutable());
    spdlog::info("batch: {} takes, {} failed -> {}", plan.takes.size(), failed,
                 (day / "report.html").string());
    return failed == 0 ? 0 : 1;
  };
}

}  // namespace hmc
