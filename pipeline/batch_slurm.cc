#include "pipeline/batch_slurm.h"

#include <sys/stat.h>

#include <chrono>
#include <thread>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "core/error.h"
#include "core/file_util.h"
#include "core/text.h"
#include "pipeline/subprocess.h"

namespace hmc {

namespace fs = std::filesystem;

namespace {

// A word for sh: single-quoted.
std::string Quote(const std::string& word) {
  std::string out = "'";
  for (char c : word) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

void WriteScript(const fs::path& file, const std::string& text) {
  WriteFileAtomic(file, text);
  chmod(file.c_str(), 0755);
}

std::string JobList(const SlurmJobs& jobs) {
  std::string list;
  for (const std::string* id : {&jobs.index, &jobs.first, &jobs.array, &jobs.merge, &jobs.report}) {
    if (!id->empty()) list += (list.empty() ? "" : ",") + *id;
  }
  return list;
}

// squeue's lines "ID STATE" for `jobs` (arrays one line per task); empty
// when none is queued (squeue refuses ids it has forgotten: none queued).
std::vector<std::pair<std::string, std::string>> Queue(const SlurmJobs& jobs) {
  std::vector<std::pair<std::string, std::string>> lines;
  const std::string list = JobList(jobs);
  if (list.empty()) return lines;
  std::string out;
  if (CaptureProcess({"squeue", "-h", "-r", "-j", list, "-o", "%i %T"}, &out) != 0) return lines;
  ForEachLine(out, [&](int, std::string_view line) {
    const std::vector<std::string_view> words = SplitWhitespace(line);
    if (words.size() == 2) lines.emplace_back(std::string(words[0]), std::string(words[1]));
  });
  return lines;
}

std::string Sbatch(const std::vector<std::string>& args) {
  std::vector<std::string> command = {"sbatch", "--parsable"};
  command.insert(command.end(), args.begin(), args.end());
  std::string out, err;
  const int code = CaptureProcess(command, &out, &err);
  if (code != 0) {
    std::string line;
    for (const std::string& a : command) line += " " + a;
    throw InputError(fmt::format("sbatch refused a job (exit {}):{}\n{}", code, line, err));
  }
  // --parsable: "ID" or "ID;cluster".
  std::string id = out.substr(0, out.find_first_of(";\r\n"));
  HMC_CHECK_MSG(!id.empty(), "sbatch printed no job id");
  return id;
}

}  // namespace

SlurmJobs ReadSlurmJobs(const fs::path& day) {
  SlurmJobs jobs;
  const fs::path file = day / ".batch" / "slurm.json";
  std::error_code ec;
  if (!fs::is_regular_file(file, ec)) return jobs;
  const nlohmann::json json = nlohmann::json::parse(ReadFile(file), nullptr, false);
  if (!json.is_object()) ThrowInputError(file, 0, "damaged: not JSON");
  jobs.index = json.value("index", "");
  jobs.array = json.value("array", "");
  jobs.report = json.value("report", "");
  jobs.first = json.value("first", "");
  jobs.merge = json.value("merge", "");
  if (json.contains("tasks")) jobs.tasks = json["tasks"].get<std::map<std::string, int>>();
  return jobs;
}

SlurmJobs SubmitSlurmBatch(const fs::path& day, const BatchPlan& plan, const BatchOptions& options,
                           const fs::path& hmc_binary) {
  if (!OnPath("sbatch")) {
    throw InputError("--scheduler slurm: sbatch is not on PATH (install slurm-client, or run "
                     "on a submit host of the cluster)");
  }
  const SlurmJobs previous = ReadSlurmJobs(day);
  if (!Queue(previous).empty()) {
    throw InputError(fmt::format(
        "{}: jobs {} of an earlier submission are still in the queue: hmc batch --status {} "
        "--wait, or scancel them, before submitting again",
        day.string(), JobList(previous), day.string()));
  }
  SlurmJobs jobs;
  // Every unit of the day has a line of takes.txt (its array index is the
  // line, minus one); the three arrays list the units still to do.
  std::string takes_txt, first, array, merge;
  int line = 0;
  for (const Take& take : plan.takes) {
    const bool complete = TakeIsComplete(day, plan, take);
    if (complete) spdlog::info("batch: take {} complete: kept", take.name);
    for (const std::string& unit : TakeUnits(take)) {
      const int i = line++;
      takes_txt += unit + "\n";
      if (complete || (unit != take.name && UnitIsComplete(day, plan, unit))) continue;
      jobs.tasks[unit] = i;
      const std::string part = SplitUnit(unit).second;
      std::string& list = part == "calibrate" ? first
                          : part.empty() && !take.chunks.empty() ? merge
                                                                  : array;
      list += (list.empty() ? "" : ",") + std::to_string(i);
    }
  }
  if (jobs.tasks.empty()) {
    spdlog::info("batch: every take is complete; nothing to submit");
    WriteDayFiles(day, CollectBatch(day, "slurm", [](const std::string&) { return ""; }));
    return previous;
  }
  const fs::path dir = day / ".batch" / "slurm";
  EnsureDirectory(dir);
  EnsureDirectory(day / "logs");
  WriteFileAtomic(day / ".batch" / "takes.txt", takes_txt);
  const std::string d = Quote(day.string());
  const std::string hmc = Quote(hmc_binary.string());
  const std::string head = fmt::format(
      "#!/bin/sh\n# Written by hmc batch (docs/farm.md); runs on a node of the cluster.\n"
      "export XDG_CACHE_HOME={}\n",
      Quote(DayIndexCache(day).string()));
  std::string index = "exec " + hmc;
  for (const std::string& arg : IndexArgs(day, plan)) index += " " + Quote(arg);
  WriteScript(dir / "index.sh", head + index + "\n");
  WriteScript(dir / "take.sh",
              head + fmt::format("take=$(sed -n \"$((SLURM_ARRAY_TASK_ID + 1))p\" {}/.batch/takes.txt)\n"
                                 "exec {} --threads \"${{SLURM_CPUS_PER_TASK:-0}}\" batch --out {} "
                                 "--take \"$take\" >{}/logs/\"$take\".log 2>&1\n",
                                 d, hmc, d, d));
  WriteScript(dir / "report.sh",
              head + fmt::format("exec {} batch --out {} --day_report --scheduler slurm\n", hmc, d));
  std::vector<std::string> common;
  if (!options.slurm_partition.empty()) common.push_back("--partition=" + options.slurm_partition);
  if (!options.slurm_time.empty()) common.push_back("--time=" + options.slurm_time);
  if (!options.slurm_account.empty()) common.push_back("--account=" + options.slurm_account);
  common.insert(common.end(), options.slurm_extra.begin(), options.slurm_extra.end());
  const std::string logs = (day / "logs").string();
  auto job = [&](const std::string& name, std::vector<std::string> args) {
    std::vector<std::string> all = {"--job-name=hmc-" + name, "--chdir=" + day.string()};
    all.insert(all.end(), common.begin(), common.end());
    all.insert(all.end(), args.begin(), args.end());
    return Sbatch(all);
  };
  jobs.index = job("index", {"--output=" + logs + "/slurm-index-%j.out",
                             fmt::format("--cpus-per-task={}", options.slurm_cpus),
                             (dir / "index.sh").string()});
  // The arrays in their order, each after the job before it.
  std::string after = jobs.index;
  auto submit_array = [&](const std::string& name, const std::string& list) {
    std::vector<std::string> args = {"--output=" + logs + "/slurm-" + name + "-%A_%a.out",
                                     "--array=" + list, "--dependency=afterany:" + after,
                                     fmt::format("--cpus-per-task={}", options.slurm_cpus)};
    if (!options.slurm_mem.empty()) args.push_back("--mem=" + options.slurm_mem);
    args.push_back((dir / "take.sh").string());
    after = job(name, args);
    return after;
  };
  if (!first.empty()) jobs.first = submit_array("first", first);
  if (!array.empty()) jobs.array = submit_array("take", array);
  if (!merge.empty()) jobs.merge = submit_array("merge", merge);
  jobs.report = job("report", {"--output=" + logs + "/slurm-report-%j.out",
                               "--dependency=afterany:" + after, (dir / "report.sh").string()});
  const nlohmann::json json = {{"index", jobs.index},
                               {"first", jobs.first},
                               {"array", jobs.array},
                               {"merge", jobs.merge},
                               {"report", jobs.report},
                               {"tasks", jobs.tasks}};
  WriteFileAtomic(day / ".batch" / "slurm.json", json.dump(1) + "\n");
  spdlog::info("batch: submitted {} tasks: index job {}, first passes {} [{}], array {} [{}], "
               "merges {} [{}], day report {}",
               jobs.tasks.size(), jobs.index, jobs.first, first, jobs.array, array, jobs.merge,
               merge, jobs.report);
  // batch.json now, so that it lists the day from the start.
  WriteDayFiles(day, CollectBatch(day, "slurm", [&](const std::string& unit) {
                  return jobs.tasks.count(unit) ? std::string("PENDING") : std::string();
                }));
  return jobs;
}

std::map<std::string, std::string> SlurmTakeQueue(const SlurmJobs& jobs) {
  std::map<std::string, std::string> out;
  std::map<int, std::string> by_index;
  for (const auto& [unit, index] : jobs.tasks) by_index[index] = unit;
  for (const auto& [id, state] : Queue(jobs)) {
    for (const std::string* array : {&jobs.first, &jobs.array, &jobs.merge}) {
      if (array->empty() || id.rfind(*array + "_", 0) != 0) continue;
      int index = -1;
      if (ParseInt(id.substr(array->size() + 1), &index) && by_index.count(index)) {
        const std::string& unit = by_index[index];
        out[unit] = state;
        std::string& take = out[SplitUnit(unit).first];
        if (take != "RUNNING") take = state;
      }
    }
  }
  // The index job pending holds every take of the array.
  return out;
}

void WaitSlurmJobs(const SlurmJobs& jobs) {
  while (!Queue(jobs).empty()) std::this_thread::sleep_for(std::chrono::milliseconds(250));
}

std::string SlurmQueueText(const SlurmJobs& jobs) {
  if (jobs.index.empty()) return "";
  std::string out = fmt::format("slurm jobs: index {}, takes {}, day report {}", jobs.index,
                                jobs.array, jobs.report);
  if (!jobs.first.empty() || !jobs.merge.empty()) {
    out += fmt::format(" (chunked takes: first passes {}, merges {})", jobs.first, jobs.merge);
  }
  out += "\n";
  for (const auto& [id, state] : Queue(jobs)) out += fmt::format("  {} {}\n", id, state);
  return out;
}

}  // namespace hmc
