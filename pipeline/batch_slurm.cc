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
  for (const std::string* id : {&jobs.index, &jobs.array, &jobs.report}) {
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
  std::string takes_txt, array;
  for (size_t i = 0; i < plan.takes.size(); ++i) {
    const Take& take = plan.takes[i];
    takes_txt += take.name + "\n";
    if (TakeIsComplete(day, plan, take)) {
      spdlog::info("batch: take {} complete: kept", take.name);
      continue;
    }
    jobs.tasks[take.name] = static_cast<int>(i);
    array += (array.empty() ? "" : ",") + std::to_string(i);
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
  std::vector<std::string> take_args = {"--output=" + logs + "/slurm-take-%A_%a.out",
                                        "--array=" + array, "--dependency=afterany:" + jobs.index,
                                        fmt::format("--cpus-per-task={}", options.slurm_cpus)};
  if (!options.slurm_mem.empty()) take_args.push_back("--mem=" + options.slurm_mem);
  take_args.push_back((dir / "take.sh").string());
  jobs.array = job("take", take_args);
  jobs.report = job("report", {"--output=" + logs + "/slurm-report-%j.out",
                               "--dependency=afterany:" + jobs.array, (dir / "report.sh").string()});
  const nlohmann::json json = {{"index", jobs.index},
                               {"array", jobs.array},
                               {"report", jobs.report},
                               {"tasks", jobs.tasks}};
  WriteFileAtomic(day / ".batch" / "slurm.json", json.dump(1) + "\n");
  spdlog::info("batch: submitted {} takes: index job {}, array {} [{}], day report {}",
               jobs.tasks.size(), jobs.index, jobs.array, array, jobs.report);
  // batch.json now, so that it lists the day from the start.
  WriteDayFiles(day, CollectBatch(day, "slurm", [&](const std::string& take) {
                  return jobs.tasks.count(take) ? std::string("PENDING") : std::string();
                }));
  return jobs;
}

std::map<std::string, std::string> SlurmTakeQueue(const SlurmJobs& jobs) {
  std::map<std::string, std::string> out;
  if (jobs.array.empty()) return out;
  std::map<int, std::string> by_index;
  for (const auto& [take, index] : jobs.tasks) by_index[index] = take;
  for (const auto& [id, state] : Queue(jobs)) {
    if (id.rfind(jobs.array + "_", 0) != 0) continue;
    int index = -1;
    if (ParseInt(id.substr(jobs.array.size() + 1), &index) && by_index.count(index)) {
      out[by_index[index]] = state;
    }
  }
  // The index job pending holds every take of the array.
  return out;
}

void WaitSlurmJobs(const SlurmJobs& jobs) {
  while (!Queue(jobs).empty()) std::this_thread::sleep_for(std::chrono::milliseconds(250));
}

std::string SlurmQueueText(const SlurmJobs& jobs) {
  if (jobs.array.empty()) return "";
  std::string out = fmt::format("slurm jobs: index {}, takes {}, day report {}\n", jobs.index,
                                jobs.array, jobs.report);
  for (const auto& [id, state] : Queue(jobs)) out += fmt::format("  {} {}\n", id, state);
  return out;
}

}  // namespace hmc
