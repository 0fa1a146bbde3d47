#include "pipeline/batch.h"

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <ctime>
#include <map>
#include <set>
#include <thread>

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <yaml-cpp/yaml.h>

#include "core/calibration.h"
#include "core/error.h"
#include "core/file_util.h"
#include "core/hash.h"
#include "core/text.h"
#include "pipeline/subprocess.h"
#include "pipeline/svg_plot.h"
#include "pipeline/track_chunks.h"
#include "tracking/footage_reader.h"

namespace hmc {

namespace fs = std::filesystem;

void BatchOptions::Register(OptionFields* fields) {
  fields->Add("scheduler", &scheduler,
              "Where the takes run: local (this machine, --jobs at a time) or slurm "
              "(sbatch job array)")
      .OneOf({"local", "slurm"});
  fields->Add("jobs", &jobs, "Takes at a time with the local scheduler (0 = the cores)")
      .AtLeast(0);
  fields->SetGroup("slurm");
  fields->Add("partition", &slurm_partition, "sbatch --partition (\"\" = the cluster's default)");
  fields->Add("time", &slurm_time, "sbatch --time per task, as SLURM reads it (\"2:00:00\")");
  fields->Add("mem", &slurm_mem,
              "sbatch --mem per task (\"2G\"; docs/farm.md measures a take; \"\" = the default)");
  fields->Add("cpus", &slurm_cpus, "sbatch --cpus-per-task: cores per take").In(1, 4096);
  fields->Add("account", &slurm_account, "sbatch --account (\"\" = none)");
  fields->Add("extra", &slurm_extra, "More sbatch arguments for every job (\"--qos=low\")");
  fields->SetGroup("");
  fields->Add("chunk_frames", &chunk_frames,
              "--chunk-frames N: track a take longer than N frames in chunks of N frames, each "
              "a task of its own; the take's run then merges them and runs the later stages on "
              "the whole take (0 = one task per take; docs/farm.md)")
      .AtLeast(0);
  fields->Add("chunk_overlap", &chunk_overlap,
              "Frames a chunk also tracks before its own, so that its labels are settled")
      .AtLeast(0);
}

bool BatchOptions::Check() const {
  CHECK_OPTION_LIMITS();
  return true;
}

namespace {

// Takes are folder names in DAY; hidden ones and the names of the day's
// own files and folders are the batch's.
void CheckTakeName(const std::string& name, const fs::path& file, int line) {
  const bool ok = !name.empty() && name[0] != '.' && name != "logs" && name != "batch.json" &&
                  name != "report.html" &&
                  std::all_of(name.begin(), name.end(), [](char c) {
                    return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' ||
                           c == '.';
                  });
  if (!ok) {
    ThrowInputError(file, line,
                    "take name '{}' is not a folder name hmc batch can use (letters, digits, "
                    "'_', '-', '.' not first; not logs, batch.json or report.html)",
                    name);
  }
}

// A shot folder's camera: a video SHOT/<cam>.<ext> or an image folder.
bool HasCamera(const fs::path& shot, const std::string& cam) {
  std::error_code ec;
  if (fs::is_directory(shot / cam, ec)) return true;
  for (const auto& e : fs::directory_iterator(shot, ec)) {
    if (e.path().stem() == cam && e.is_regular_file(ec)) return true;
  }
  return false;
}

fs::path Resolve(const fs::path& base, const std::string& path) {
  return fs::absolute(fs::path(path).is_absolute() ? fs::path(path) : base / path)
      .lexically_normal();
}

std::string NowUtc() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char text[32];
  std::strftime(text, sizeof text, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return text;
}

nlohmann::json ReadJsonOrNull(const fs::path& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) return nullptr;
  try {
    return nlohmann::json::parse(ReadFile(path), nullptr, false);
  } catch (const InputError&) {
    return nullptr;
  }
}

fs::path StateFile(const fs::path& day, const std::string& take) {
  return day / ".batch" / "takes" / (take + ".json");
}

void WriteTakeState(const fs::path& day, const std::string& take, const nlohmann::json& state) {
  EnsureDirectory(StateFile(day, take).parent_path());
  WriteFileAtomic(StateFile(day, take), state.dump(1) + "\n");
}

}  // namespace

std::vector<Take> ReadTakes(const fs::path& takes) {
  std::vector<Take> out;
  std::error_code ec;
  if (fs::is_directory(takes, ec)) {
    std::vector<fs::path> folders;
    for (const auto& e : fs::directory_iterator(takes, ec)) {
      if (e.is_directory(ec) && e.path().filename().string()[0] != '.') folders.push_back(e.path());
    }
    std::sort(folders.begin(), folders.end());
    for (const fs::path& f : folders) {
      if (!HasCamera(f, "cam0") && !HasCamera(f, "cam1")) {
        spdlog::info("batch: {} holds no footage (cam0, cam1): not a take", f.string());
        continue;
      }
      CheckTakeName(f.filename().string(), f, 0);
      out.push_back({f.filename().string(), fs::absolute(f).lexically_normal().string(), "", "", {}});
    }
    if (out.empty()) {
      ThrowInputError(takes, 0, "no sub-folder holds footage (cam0 and cam1 videos or image "
                                "folders): no takes");
    }
  } else {
    const std::string problem = DescribeUnreadable(takes);
    if (!problem.empty()) ThrowInputError(takes, 0, "--takes {}", problem);
    const fs::path base = fs::absolute(takes).parent_path();
    const std::string ext = takes.extension().string();
    auto add = [&](Take take, int line) {
      if (take.shot.empty()) ThrowInputError(takes, line, "a take without a shot folder");
      if (take.name.empty()) take.name = fs::path(take.shot).lexically_normal().filename().string();
      CheckTakeName(take.name, takes, line);
      take.shot = Resolve(base, take.shot).string();
      if (!fs::is_directory(take.shot, ec)) {
        ThrowInputError(takes, line, "take '{}': shot folder {} does not exist", take.name,
                        take.shot);
      }
      if (!take.calibration.empty()) take.calibration = Resolve(base, take.calibration).string();
      for (const Take& t : out) {
        if (t.name == take.name) ThrowInputError(takes, line, "take '{}' listed twice", take.name);
      }
      out.push_back(take);
    };
    if (ext == ".yaml" || ext == ".yml") {
      const YAML::Node root = LoadYamlFile(takes);
      const YAML::Node list = root.IsMap() ? root["takes"] : root;
      if (!list || !list.IsSequence()) {
        ThrowInputError(takes, 1, "expected a sequence of takes under 'takes:'");
      }
      for (const YAML::Node& item : list) {
        const int line = item.Mark().line + 1;
        Take take;
        if (item.IsScalar()) {
          take.shot = item.as<std::string>();
        } else if (item.IsMap()) {
          for (const auto& kv : item) {
            const std::string key = kv.first.as<std::string>();
            std::string* field = key == "name"          ? &take.name
                                 : key == "shot"        ? &take.shot
                                 : key == "frames"      ? &take.frames
                                 : key == "calibration" ? &take.calibration
                                                        : nullptr;
            if (field == nullptr) {
              ThrowInputError(takes, kv.first.Mark().line + 1,
                              "unknown key '{}' (a take has name, shot, frames, calibration)",
                              key);
            }
            *field = kv.second.as<std::string>();
          }
        } else {
          ThrowInputError(takes, line, "a take is a shot folder or a mapping");
        }
        add(take, line);
      }
    } else if (ext == ".csv") {
      std::vector<std::string> header;
      ForEachLine(ReadFile(takes), [&](int line, std::string_view text) {
        if (Trim(text).empty() || Trim(text)[0] == '#') return;
        std::vector<std::string> fields = SplitCsvRecord(text, takes, line);
        for (std::string& f : fields) f = std::string(Trim(f));
        if (header.empty()) {
          header = fields;
          for (const std::string& h : header) {
            if (h != "name" && h != "shot" && h != "frames" && h != "calibration") {
              ThrowInputError(takes, line,
                              "unknown column '{}' (columns: name, shot, frames, calibration)", h);
            }
          }
          if (std::find(header.begin(), header.end(), "shot") == header.end()) {
            ThrowInputError(takes, line, "the header names no 'shot' column");
          }
          return;
        }
        if (fields.size() > header.size()) {
          ThrowInputError(takes, line, "{} fields, the header has {}", fields.size(),
                          header.size());
        }
        Take take;
        for (size_t i = 0; i < fields.size(); ++i) {
          if (header[i] == "name") take.name = fields[i];
          if (header[i] == "shot") take.shot = fields[i];
          if (header[i] == "frames") take.frames = fields[i];
          if (header[i] == "calibration") take.calibration = fields[i];
        }
        add(take, line);
      });
    } else {
      ThrowInputError(takes, 0,
                      "--takes is a folder of shot folders or a .yaml/.yml/.csv list of takes");
    }
    if (out.empty()) ThrowInputError(takes, 0, "lists no takes");
  }
  return out;
}

const Take* BatchPlan::Find(const std::string& name) const {
  for (const Take& t : takes) {
    if (t.name == name) return &t;
  }
  return nullptr;
}

void WritePlan(const fs::path& day, const BatchPlan& plan) {
  nlohmann::json takes = nlohmann::json::array();
  for (const Take& t : plan.takes) {
    takes.push_back({{"name", t.name},
                     {"shot", t.shot},
                     {"frames", t.frames},
                     {"calibration", t.calibration},
                     {"chunks", t.chunks}});
  }
  const nlohmann::json json = {{"stage", "batch"},
                               {"actor", plan.actor},
                               {"calibration", plan.calibration},
                               {"run_config", plan.run_config},
                               {"chunk_overlap", plan.chunk_overlap},
                               {"takes", takes}};
  EnsureDirectory(day / ".batch");
  WriteFileAtomic(day / ".batch" / "plan.json", json.dump(1) + "\n");
}

BatchPlan ReadPlan(const fs::path& day) {
  const fs::path file = day / ".batch" / "plan.json";
  const nlohmann::json json = ReadJsonOrNull(file);
  if (!json.is_object() || !json.contains("takes")) {
    ThrowInputError(file, 0, "not the plan of an hmc batch (run hmc batch --takes ... --out {} "
                             "first)",
                    day.string());
  }
  BatchPlan plan;
  try {
    plan.actor = json.at("actor").get<std::string>();
    plan.calibration = json.at("calibration").get<std::string>();
    plan.run_config = json.at("run_config").get<std::string>();
    plan.chunk_overlap = json.value("chunk_overlap", 0);
    for (const auto& t : json.at("takes")) {
      plan.takes.push_back({t.at("name").get<std::string>(), t.at("shot").get<std::string>(),
                            t.at("frames").get<std::string>(),
                            t.at("calibration").get<std::string>(),
                            t.value("chunks", std::vector<std::pair<int, int>>())});
    }
  } catch (const nlohmann::json::exception& e) {
    ThrowInputError(file, 0, "damaged batch plan: {}", e.what());
  }
  return plan;
}

std::string WriteRunConfig(const fs::path& day, const std::string& config) {
  EnsureDirectory(day / ".batch");
  const fs::path file = day / ".batch" / "run.yaml";
  const fs::path index_file = day / ".batch" / "index.yaml";
  std::error_code ec;
  fs::remove(file, ec);
  fs::remove(index_file, ec);
  if (config.empty()) return "";
  YAML::Node root = LoadYamlFile(config);
  YAML::Node run_config(YAML::NodeType::Map);
  YAML::Node index_config(YAML::NodeType::Map);
  if (root.IsMap()) {
    for (const auto& kv : root) {
      if (kv.first.as<std::string>() != "batch") run_config[kv.first] = kv.second;
    }
    // The solve's index options: the shared index must be the one the
    // takes' solves look for.
    const YAML::Node solve = root["solve"];
    for (const char* group : {"index", "nn"}) {
      if (solve && solve.IsMap() && solve[group]) index_config[group] = solve[group];
    }
  }
  auto write = [](const fs::path& path, const YAML::Node& node, const char* what) {
    YAML::Emitter emitter;
    emitter << node;
    WriteFileAtomic(path, std::string("# ") + what + " (hmc batch)\n" + emitter.c_str() + "\n");
  };
  write(file, run_config, "the run config of every take");
  if (index_config.size() > 0) write(index_file, index_config, "the solve's index options");
  return fs::absolute(file).string();
}

std::vector<std::string> IndexArgs(const fs::path& day, const BatchPlan& plan) {
  std::vector<std::string> args = {"index", "--actor", plan.actor};
  std::error_code ec;
  const fs::path index_file = fs::absolute(day / ".batch" / "index.yaml");
  if (fs::is_regular_file(index_file, ec)) args.insert(args.end(), {"--config", index_file.string()});
  return args;
}

fs::path DayIndexCache(const fs::path& day) { return fs::absolute(day / ".batch" / "cache"); }

std::vector<std::string> TakeRunArgs(const fs::path& day, const BatchPlan& plan,
                                     const Take& take) {
  std::vector<std::string> args = {
      "run",           "--shot",
      take.shot,       "--actor",
      plan.actor,      "--calibration",
      take.calibration.empty() ? plan.calibration : take.calibration,
      "--out",         fs::absolute(day / take.name).lexically_normal().string()};
  if (!plan.run_config.empty()) args.insert(args.end(), {"--config", plan.run_config});
  if (!take.frames.empty()) args.insert(args.end(), {"--frames", take.frames});
  return args;
}

void PlanChunks(BatchPlan* plan, int chunk_frames, int chunk_overlap) {
  plan->chunk_overlap = chunk_overlap;
  // The footage options the takes' runs get from the run config.
  FootageOptions footage;
  if (!plan->run_config.empty()) {
    const YAML::Node run = LoadYamlFile(plan->run_config)["run"];
    if (run && run.IsMap()) {
      for (const auto& [key, field] : {std::pair{"cam0", &footage.cam0},
                                       std::pair{"cam1", &footage.cam1},
                                       std::pair{"frames", &footage.frames}}) {
        if (run[key]) *field = run[key].as<std::string>();
      }
      if (run["offset1"]) footage.offset1 = run["offset1"].as<int>();
    }
  }
  for (Take& take : plan->takes) {
    take.chunks.clear();
    if (chunk_frames <= 0) continue;
    int first = 0, last = 0;
    try {
      FootageOptions options = footage;
      if (!take.frames.empty()) options.frames = take.frames;
      const HelmetRig rig =
          ReadCalibration(take.calibration.empty() ? plan->calibration : take.calibration);
      std::vector<std::string> names;
      for (const HelmetCamera& c : rig.cameras) names.push_back(c.name);
      const FootageReader reader(take.shot, names, options);
      first = reader.first_frame();
      last = reader.last_frame();
    } catch (const std::exception& e) {
      spdlog::warn("batch: take {}: {}: not chunked", take.name, e.what());
      continue;
    }
    if (last - first + 1 <= chunk_frames) continue;
    for (int a = first; a <= last; a += chunk_frames) {
      take.chunks.emplace_back(a, std::min(last, a + chunk_frames - 1));
    }
    spdlog::info("batch: take {} (frames {}-{}) in {} chunks of {} frames", take.name, first, last,
                 take.chunks.size(), chunk_frames);
  }
}

std::vector<std::string> TakeUnits(const Take& take) {
  if (take.chunks.empty()) return {take.name};
  std::vector<std::string> units = {take.name + "@calibrate"};
  for (size_t k = 0; k < take.chunks.size(); ++k) units.push_back(fmt::format("{}@chunk{}", take.name, k));
  units.push_back(take.name);
  return units;
}

std::pair<std::string, std::string> SplitUnit(const std::string& unit) {
  const size_t at = unit.find('@');
  if (at == std::string::npos) return {unit, ""};
  return {unit.substr(0, at), unit.substr(at + 1)};
}

std::vector<std::string> UnitDependencies(const BatchPlan& plan, const std::string& unit) {
  const auto [name, part] = SplitUnit(unit);
  const Take* take = plan.Find(name);
  if (take == nullptr || take->chunks.empty() || part == "calibrate") return {};
  if (!part.empty()) return {name + "@calibrate"};
  std::vector<std::string> units = TakeUnits(*take);
  units.pop_back();
  return units;
}

namespace {

// A chunk's workspace: DAY/.batch/chunks/<take>/<K>.
fs::path ChunkWork(const fs::path& day, const std::string& take, size_t k) {
  return fs::absolute(day / ".batch" / "chunks" / take / std::to_string(k)).lexically_normal();
}

// The list of a chunked take's chunks its run merges (pipeline/track_chunks.h).
fs::path ChunkList(const fs::path& day, const std::string& take) {
  return fs::absolute(day / ".batch" / "chunks" / take / "chunks.json").lexically_normal();
}

std::vector<TrackChunk> TakeChunks(const fs::path& day, const BatchPlan& plan, const Take& take) {
  std::vector<TrackChunk> chunks;
  const int first = take.chunks.empty() ? 0 : take.chunks.front().first;
  for (size_t k = 0; k < take.chunks.size(); ++k) {
    const auto [a, b] = take.chunks[k];
    chunks.push_back({ChunkWork(day, take.name, k).string(), a, b,
                      std::max(first, a - plan.chunk_overlap)});
  }
  return chunks;
}

}  // namespace

std::vector<std::string> UnitRunArgs(const fs::path& day, const BatchPlan& plan,
                                     const std::string& unit) {
  const auto [name, part] = SplitUnit(unit);
  const Take* take = plan.Find(name);
  int chunk = -1;
  if (take != nullptr && part.rfind("chunk", 0) == 0 && ParseInt(part.substr(5), &chunk) &&
      (chunk < 0 || chunk >= static_cast<int>(take->chunks.size()))) {
    chunk = -2;
  }
  if (take == nullptr || (!part.empty() && take->chunks.empty()) ||
      (!part.empty() && part != "calibrate" && chunk < 0)) {
    throw InputError(fmt::format("{}: the day has no take or chunk '{}'",
                                 (day / ".batch" / "plan.json").string(), unit));
  }
  std::vector<std::string> args = TakeRunArgs(day, plan, *take);
  if (take->chunks.empty()) return args;
  if (part.empty()) {
    args.insert(args.end(), {"--track_chunks", ChunkList(day, name).string()});
  } else if (part == "calibrate") {
    args.insert(args.end(), {"--to", "calibrate"});
  } else {
    // The chunk's frames and the overlap before them, tracked with the
    // take's calibration (its first pass) as it is.
    const TrackChunk c = TakeChunks(day, plan, *take)[chunk];
    args = {"run",          "--shot",
            take->shot,     "--actor",
            plan.actor,     "--calibration",
            fs::absolute(day / name / "calibrate" / "calibration.yaml").lexically_normal().string(),
            "--calibrate",  "false",
            "--out",        c.work};
    if (!plan.run_config.empty()) args.insert(args.end(), {"--config", plan.run_config});
    args.insert(args.end(), {"--frames", fmt::format("{}:{}", c.tracked_first, c.last), "--to",
                             "track"});
  }
  return args;
}

fs::path TakeLog(const fs::path& day, const std::string& take) {
  return day / "logs" / (take + ".log");
}

nlohmann::json ReadTakeState(const fs::path& day, const std::string& take) {
  return ReadJsonOrNull(StateFile(day, take));
}

namespace {

// What the day-level skip of a take compares besides its command line: the
// run config's and the calibration's contents, and every file of the shot
// folder and the actor package by path, size and modification time (cheap:
// no footage is read; hmc run itself then compares contents stage by
// stage).
std::string TakeInputs(const fs::path& day, const BatchPlan& plan, const Take& take,
                       const std::string& unit) {
  ContentHasher hash;
  std::error_code ec;
  // A chunk tracks with its take's first pass's calibration.
  if (SplitUnit(unit).second.rfind("chunk", 0) == 0) {
    const fs::path calibration = day / take.name / "calibrate" / "calibration.yaml";
    if (fs::is_regular_file(calibration, ec)) hash.Update(HashHex(HashFile(calibration)));
  }
  for (const std::string& file :
       {plan.run_config, take.calibration.empty() ? plan.calibration : take.calibration}) {
    if (!file.empty() && fs::is_regular_file(file, ec)) hash.Update(HashHex(HashFile(file)));
  }
  for (const std::string& folder : {take.shot, plan.actor}) {
    std::vector<std::string> entries;
    for (auto it = fs::recursive_directory_iterator(folder, ec);
         !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
      if (!it->is_regular_file(ec)) continue;
      const auto time = fs::last_write_time(it->path(), ec).time_since_epoch().count();
      entries.push_back(fmt::format("{}\t{}\t{}", it->path().string(),
                                    fs::file_size(it->path(), ec), time));
    }
    std::sort(entries.begin(), entries.end());
    for (const std::string& e : entries) hash.Update(e + "\n");
  }
  return HashHex(hash.Digest());
}

}  // namespace

bool UnitIsComplete(const fs::path& day, const BatchPlan& plan, const std::string& unit) {
  const nlohmann::json state = ReadTakeState(day, unit);
  const std::vector<std::string> args = UnitRunArgs(day, plan, unit);
  // The unit's workspace: the value of --out.
  const auto out = std::find(args.begin(), args.end(), "--out");
  std::error_code ec;
  return state.is_object() && state.value("state", "") == "done" &&
         state.value("args", nlohmann::json()) == nlohmann::json(args) &&
         state.value("inputs", "") ==
             TakeInputs(day, plan, *plan.Find(SplitUnit(unit).first), unit) &&
         out != args.end() && out + 1 != args.end() && fs::is_directory(*(out + 1), ec);
}

bool TakeIsComplete(const fs::path& day, const BatchPlan& plan, const Take& take) {
  return UnitIsComplete(day, plan, take.name);
}

int RunTake(const fs::path& day, const BatchPlan& plan, const std::string& name,
            const BatchCommandRunner& run_command) {
  const std::vector<std::string> args = UnitRunArgs(day, plan, name);
  const Take* take = plan.Find(SplitUnit(name).first);
  // A chunked take's run merges the chunks this list names.
  if (name == take->name && !take->chunks.empty()) {
    WriteTrackChunks(ChunkList(day, name), TakeChunks(day, plan, *take));
  }
  nlohmann::json state = {{"state", "running"}, {"args", args},
                          {"inputs", TakeInputs(day, plan, *take, name)},
                          {"started", NowUtc()}, {"pid", getpid()},
                          {"reason", ""},        {"host", ""}};
  char host[256] = {0};
  if (gethostname(host, sizeof host - 1) == 0) state["host"] = host;
  WriteTakeState(day, name, state);
  const auto start = std::chrono::steady_clock::now();
  int code = 1;
  std::string reason;
  try {
    code = run_command(args);
    if (code != 0) reason = fmt::format("hmc run exited with code {}", code);
  } catch (const std::exception& e) {
    reason = e.what();
    code = 1;
  }
  if (code == 0) {
    // The take's review page (docs/review.md), linked from the day report;
    // the take is done without it.
    const std::string work = fs::absolute(day / name).lexically_normal().string();
    try {
      if (run_command({"review", "--work", work}) != 0) spdlog::warn("batch: take {}: no review page", name);
    } catch (const std::exception& e) {
      spdlog::warn("batch: take {}: no review page: {}", name, e.what());
    }
  }
  state["finished"] = NowUtc();
  state["seconds"] = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  state["state"] = code == 0 ? "done" : "failed";
  state["reason"] = reason;
  WriteTakeState(day, name, state);
  if (code == 0) {
    spdlog::info("batch: take {} done", name);
    return 0;
  }
  spdlog::error("batch: take {} failed: {}", name, reason);
  return 1;
}

namespace {

// A number of a JSON object by path ({"a", "b"}), or null.
nlohmann::json At(const nlohmann::json& json, std::initializer_list<const char*> path) {
  const nlohmann::json* node = &json;
  for (const char* key : path) {
    if (!node->is_object() || !node->contains(key)) return nullptr;
    node = &(*node)[key];
  }
  return *node;
}

// The take's summary figures, from its workspace (null where a stage did
// not run).
nlohmann::json TakeFigures(const fs::path& work) {
  auto summary = [&](const char* stage) { return ReadJsonOrNull(work / stage / "summary.json"); };
  const nlohmann::json track = summary("track");
  const nlohmann::json tri = summary("triangulate");
  const nlohmann::json jaw = summary("jaw");
  const nlohmann::json solve = ReadJsonOrNull(work / "solve" / "diagnostics.json");
  const nlohmann::json accuracy = ReadJsonOrNull(work / "report" / "accuracy.json");
  return {
      {"frames", At(track, {"report", "command_summary", "summary", "frames"})},
      {"mean_named_dots", At(track, {"report", "command_summary", "summary", "mean_named"})},
      {"triangulation_rms_px", At(tri, {"report", "command_summary", "rms_residual_px"})},
      {"jaw_residual_mm", At(jaw, {"report", "command_summary", "mean_residual_mm"})},
      {"solve_bad_frames", At(solve, {"summary", "bad_frames"})},
      {"truth_face_mean_mm", At(accuracy, {"solve", "face_mean_mm"})},
      {"truth_face_p95_mm", At(accuracy, {"solve", "face_p95_mm"})},
  };
}

// Whether the process a "running" state names runs (on this host; a
// state from another host is taken at its word).
bool StillRunning(const nlohmann::json& state) {
  char host[256] = {0};
  gethostname(host, sizeof host - 1);
  if (state.value("host", "") != host) return true;
  const int pid = state.value("pid", 0);
  return pid > 0 && kill(pid, 0) == 0;
}

std::string FigureText(const nlohmann::json& value) {
  if (value.is_null()) return "";
  if (value.is_number_float()) return fmt::format("{:.4g}", value.get<double>());
  return value.dump();
}

}  // namespace

nlohmann::json CollectBatch(const fs::path& day, const std::string& scheduler,
                            const std::function<std::string(const std::string&)>& queue_state) {
  const BatchPlan plan = ReadPlan(day);
  nlohmann::json takes = nlohmann::json::array();
  std::map<std::string, int> counts;
  std::error_code ec;
  for (const Take& take : plan.takes) {
    const nlohmann::json state = ReadTakeState(day, take.name);
    std::string s = state.is_object() ? state.value("state", "pending") : "pending";
    std::string reason = state.is_object() ? state.value("reason", "") : "";
    // A chunked take's first pass and chunks, each a task of its own.
    nlohmann::json chunks = nlohmann::json::array();
    for (const std::string& unit : TakeUnits(take)) {
      if (unit == take.name) continue;
      const nlohmann::json u = ReadTakeState(day, unit);
      std::string us = u.is_object() ? u.value("state", "pending") : "pending";
      if (us == "running" && queue_state(unit).empty() && !StillRunning(u)) us = "incomplete";
      if (us == "running" && s == "pending") s = "running";
      chunks.push_back({{"unit", unit},
                        {"state", us},
                        {"reason", u.is_object() ? u.value("reason", "") : ""},
                        {"seconds", u.is_object() ? u.value("seconds", 0.0) : 0.0},
                        {"log", "logs/" + unit + ".log"}});
    }
    const std::string queued = queue_state(take.name);
    if (!queued.empty() && s != "running") {
      s = "queued";
      reason = "";
    }
    if (s == "running" && queued.empty() && !StillRunning(state)) {
      s = "incomplete";
      reason = "the take's process ended before it finished (killed or cancelled): the next "
               "hmc batch redoes it";
    }
    const fs::path work = day / take.name;
    const nlohmann::json report_summary = ReadJsonOrNull(work / "report" / "summary.json");
    nlohmann::json warnings = At(report_summary, {"report", "command_summary", "warnings"});
    if (!warnings.is_array()) warnings = nlohmann::json::array();
    std::string thumbnail;
    for (const char* picture : {"contact_sheet.png", "mesh_error.png"}) {
      if (thumbnail.empty() && fs::is_regular_file(work / "report" / picture, ec)) {
        thumbnail = take.name + "/report/" + picture;
      }
    }
    const bool has_report = fs::is_regular_file(work / "report" / "report.html", ec);
    const bool has_review = fs::is_regular_file(work / "review" / "index.html", ec);
    ++counts[s];
    takes.push_back({{"name", take.name},
                     {"shot", take.shot},
                     {"frames", take.frames},
                     {"calibration", take.calibration.empty() ? plan.calibration : take.calibration},
                     {"state", s},
                     {"reason", reason},
                     {"log", fs::is_regular_file(TakeLog(day, take.name), ec)
                                 ? "logs/" + take.name + ".log"
                                 : ""},
                     {"started", state.is_object() ? state.value("started", "") : ""},
                     {"finished", state.is_object() ? state.value("finished", "") : ""},
                     {"seconds", state.is_object() ? state.value("seconds", 0.0) : 0.0},
                     {"host", state.is_object() ? state.value("host", "") : ""},
                     {"figures", TakeFigures(work)},
                     {"warnings", warnings},
                     {"report", has_report ? take.name + "/report/report.html" : ""},
                     {"review", has_review ? take.name + "/review/index.html" : ""},
                     {"thumbnail", thumbnail},
                     {"chunks", chunks}});
  }
  return {{"stage", "batch"},   {"scheduler", scheduler}, {"actor", plan.actor},
          {"updated", NowUtc()}, {"counts", counts},      {"takes", takes}};
}

void WriteDayFiles(const fs::path& day, const nlohmann::json& batch) {
  WriteFileAtomic(day / "batch.json", batch.dump(1) + "\n");
  std::string rows;
  for (const auto& t : batch["takes"]) {
    std::string figures;
    for (const auto& [key, value] : t["figures"].items()) {
      if (!value.is_null()) figures += fmt::format("{}: {}<br>", key, FigureText(value));
    }
    std::string warnings;
    for (const auto& w : t["warnings"]) warnings += "<li>" + HtmlEscape(w.get<std::string>()) + "</li>";
    const std::string name = t["name"].get<std::string>();
    const std::string report = t["report"].get<std::string>();
    const std::string thumb = t["thumbnail"].get<std::string>();
    const std::string log = t["log"].get<std::string>();
    const std::string review = t.value("review", "");
    rows += fmt::format(
        "<tr class=\"{}\"><td>{}{}</td><td>{}<br>{}</td><td>{:.1f} s<br>{}</td><td>{}</td>"
        "<td><ul>{}</ul></td><td>{}</td></tr>\n",
        HtmlEscape(t["state"].get<std::string>()),
        report.empty() ? HtmlEscape(name) : fmt::format("<a href=\"{}\">{}</a>", report, HtmlEscape(name)),
        review.empty() ? "" : fmt::format("<br><a href=\"{}\">review</a>", review),
        HtmlEscape(t["state"].get<std::string>()), HtmlEscape(t["reason"].get<std::string>()),
        t["seconds"].get<double>(), log.empty() ? "" : fmt::format("<a href=\"{}\">log</a>", log),
        figures, warnings,
        thumb.empty() ? "" : fmt::format("<img src=\"{}\" width=\"240\" alt=\"{}\">", thumb, name));
  }
  std::string counts;
  for (const auto& [state, n] : batch["counts"].items()) {
    counts += fmt::format("{} {}, ", n.get<int>(), state);
  }
  if (!counts.empty()) counts.resize(counts.size() - 2);
  const std::string page = fmt::format(
      "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>hmc batch: {}</title>\n"
      "<style>body{{font-family:sans-serif}} td{{vertical-align:top;padding:4px 8px}} "
      "tr.failed,tr.incomplete{{background:#fdd}} tr.done{{background:#efe}}</style></head>\n"
      "<body><h1>Shoot day: {}</h1>\n<p>{} takes: {}; actor {}; scheduler {}; updated {}</p>\n"
      "<table><tr><th>take</th><th>state</th><th>time</th><th>figures</th><th>warnings</th>"
      "<th>thumbnail</th></tr>\n{}</table></body></html>\n",
      HtmlEscape(fs::absolute(day).filename().string()), HtmlEscape(fs::absolute(day).string()),
      batch["takes"].size(), counts, HtmlEscape(batch["actor"].get<std::string>()),
      HtmlEscape(batch["scheduler"].get<std::string>()), batch["updated"].get<std::string>(), rows);
  WriteFileAtomic(day / "report.html", page);
}

std::string StatusTable(const nlohmann::json& batch) {
  std::string out = fmt::format("{:<24} {:<10} {:>8}  {}\n", "take", "state", "seconds", "reason");
  for (const auto& t : batch["takes"]) {
    out += fmt::format("{:<24} {:<10} {:>8.1f}  {}{}\n", t["name"].get<std::string>(),
                       t["state"].get<std::string>(), t["seconds"].get<double>(),
                       t["reason"].get<std::string>(),
                       t["log"].get<std::string>().empty() ||
                               t["state"].get<std::string>() != "failed"
                           ? ""
                           : " (log: " + t["log"].get<std::string>() + ")");
  }
  return out;
}

int RunLocalBatch(const fs::path& day, const BatchPlan& plan, int jobs,
                  const fs::path& hmc_binary) {
  const unsigned cores = std::max(1u, std::thread::hardware_concurrency());
  if (jobs <= 0) jobs = static_cast<int>(cores);
  const std::map<std::string, std::string> env = {{"XDG_CACHE_HOME", DayIndexCache(day).string()}};
  EnsureDirectory(day / "logs");
  // The units to run (a take, or a chunked take's first pass, chunks and
  // merge), in order; a complete one is kept.
  std::vector<std::string> todo;
  for (const Take& take : plan.takes) {
    if (TakeIsComplete(day, plan, take)) {
      spdlog::info("batch: take {} complete: kept", take.name);
      continue;
    }
    for (const std::string& unit : TakeUnits(take)) {
      if (unit != take.name && UnitIsComplete(day, plan, unit)) {
        spdlog::info("batch: {} complete: kept", unit);
        continue;
      }
      todo.push_back(unit);
    }
  }
  if (!todo.empty()) {
    // The actor's index, once, before any take: every take's solve then
    // loads it read-only from the day's cache.
    std::vector<std::string> index_command = IndexArgs(day, plan);
    index_command.insert(index_command.begin(), hmc_binary.string());
    const int index = WaitProcess(StartProcess(index_command, env, day / "logs" / "index.log"));
    if (index != 0) {
      spdlog::warn("batch: hmc index failed (exit {}; {}): each take builds its own", index,
                   (day / "logs" / "index.log").string());
    }
  }
  // Each unit gets its share of the cores (results do not depend on it).
  const int threads = std::max(1, static_cast<int>(cores) / std::min<int>(jobs, std::max<size_t>(1, todo.size())));
  std::map<pid_t, std::string> running;
  std::set<std::string> waiting(todo.begin(), todo.end());  // not started or not ended
  int failed = 0;
  while (!waiting.empty()) {
    // Start, in order, the units whose units before them have ended
    // (whatever their end: a take whose chunk failed fails with the reason).
    for (const std::string& unit : todo) {
      if (static_cast<int>(running.size()) >= jobs) break;
      if (!waiting.count(unit) ||
          std::any_of(running.begin(), running.end(), [&](const auto& r) { return r.second == unit; })) {
        continue;
      }
      const std::vector<std::string> deps = UnitDependencies(plan, unit);
      if (std::any_of(deps.begin(), deps.end(), [&](const std::string& d) { return waiting.count(d) > 0; })) {
        continue;
      }
      fs::remove(TakeLog(day, unit));
      spdlog::info("batch: {} started", unit);
      const pid_t pid = StartProcess({hmc_binary.string(), "--threads", std::to_string(threads),
                                      "batch", "--out", fs::absolute(day).string(), "--take",
                                      unit},
                                     env, TakeLog(day, unit));
      running[pid] = unit;
    }
    int status = 0;
    const pid_t pid = waitpid(-1, &status, 0);
    if (pid < 0) break;  // nothing left to wait for (cannot happen while units wait)
    const auto it = running.find(pid);
    if (it == running.end()) continue;
    const std::string name = it->second;
    running.erase(it);
    waiting.erase(name);
    const nlohmann::json state = ReadTakeState(day, name);
    if (SplitUnit(name).second.empty() && (!state.is_object() || state.value("state", "") != "done")) {
      ++failed;
    }
    // A unit whose process died without recording its end (a crash).
    if (state.is_object() && state.value("state", "") == "running") {
      nlohmann::json crashed = state;
      crashed["state"] = "failed";
      crashed["reason"] =
          WIFSIGNALED(status)
              ? fmt::format("the take's process was killed by signal {}", WTERMSIG(status))
              : fmt::format("the take's process exited with code {}", WEXITSTATUS(status));
      crashed["finished"] = NowUtc();
      WriteFileAtomic(StateFile(day, name), crashed.dump(1) + "\n");
    }
  }
  WriteDayFiles(day, CollectBatch(day, "local", [](const std::string&) { return std::string(); }));
  return failed;
}

}  // namespace hmc
