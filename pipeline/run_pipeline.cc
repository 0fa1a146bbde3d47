#include "pipeline/run_pipeline.h"

#include <algorithm>
#include <chrono>
#include <fstream>
#include <system_error>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <spdlog/spdlog.h>
#include <yaml-cpp/yaml.h>

#include "core/actor.h"
#include "core/actor_cache.h"
#include "core/allocator.h"
#include "core/calibration.h"
#include "core/error.h"
#include "core/file_util.h"
#include "core/hash.h"
#include "core/options.h"
#include "core/text.h"
#include "pipeline/track_chunks.h"
#include "pipeline/workspace.h"
#include "tracking/footage_reader.h"
#include "tracking/video_timecode.h"

namespace hmc {

namespace fs = std::filesystem;

const std::vector<std::string>& PipelineStages() {
  static const std::vector<std::string> stages = {"calibrate", "track", "triangulate", "stabilize",
                                                  "jaw",       "solve", "report"};
  return stages;
}

void RunOptions::Register(OptionFields* fields) {
  fields->Add("from", &from, "first stage to redo even if complete (\"\" = redo only what changed)");
  fields->Add("to", &to, "last stage to run");
  footage.Register(fields);
  day.Register(fields);
  fields->Add("reference_frame", &reference_frame,
              "frame where the actor is near neutral, where track names the dots (0 = track's "
              "default, configs/track.yaml)")
      .AtLeast(0);
  fields->Add("calibrate", &calibrate,
              "refine the rig from the helmet tags (false: use --calibration as it is)");
  fields->Add("export", &export_formats,
              "mesh formats beside solve/mesh.pc2, which is always written: usda, mdd, obj "
              "(comma-separated; \"\" = none, the default: ASCII USDA is ~3x the pc2's size)");
  fields->Add("diagnostics", &diagnostics,
              "solve/diagnostics.json: summary (per frame, each observed bundle's status and "
              "residual) or full (every bundle's shapes and weights too, ~50x larger)")
      .OneOf({"summary", "full"});
  fields->Add("rays", &rays,
              "the solve uses triangulate's rays.csv, the markers seen by one camera (docs/method.md, "
              "\"Constraints after the solve\": on tracked footage they can cost accuracy)");
  fields->Add("fps", &fps,
              "frame rate of the mesh caches (frames/s; 0 = the video's own, 30 for an image "
              "sequence, which declares none)")
      .In(0, 1000);
}

namespace {

int StageIndex(const std::string& name) {
  const auto& stages = PipelineStages();
  const auto it = std::find(stages.begin(), stages.end(), name);
  return it == stages.end() ? -1 : static_cast<int>(it - stages.begin());
}

std::vector<std::string> ExportFormats(const std::string& text) {
  std::vector<std::string> formats;
  std::string_view rest(text);
  while (!rest.empty()) {
    const size_t comma = rest.find(',');
    const std::string_view item = Trim(rest.substr(0, comma));
    if (!item.empty()) formats.emplace_back(item);
    rest.remove_prefix(comma == std::string_view::npos ? rest.size() : comma + 1);
  }
  return formats;
}

}  // namespace

bool RunOptions::Check() const {
  bool ok = true;
  auto fail = [&](const std::string& message) {
    spdlog::error("run options: {}", message);
    ok = false;
  };
  if (!from.empty() && StageIndex(from) < 0) {
    fail(fmt::format("from '{}' is not a stage ({})", from, fmt::join(PipelineStages(), ", ")));
  }
  if (StageIndex(to) < 0) {
    fail(fmt::format("to '{}' is not a stage ({})", to, fmt::join(PipelineStages(), ", ")));
  }
  if (ok && !from.empty() && StageIndex(from) > StageIndex(to)) fail("from comes after to");
  if (!CheckDeclaredRanges(*this) || !footage.Check()) ok = false;
  for (const std::string& f : ExportFormats(export_formats)) {
    if (f != "usda" && f != "mdd" && f != "obj") fail(fmt::format("export format '{}' is not usda, mdd or obj", f));
  }
  return ok;
}

const std::map<std::pair<std::string, std::string>, std::string>& RunWideKeys() {
  static const std::map<std::pair<std::string, std::string>, std::string> keys = [] {
    std::map<std::pair<std::string, std::string>, std::string> k;
    for (const char* stage : {"calibrate", "track"}) {
      for (const char* key : {"cam0", "cam1", "frames", "offset1"}) {
        k[{stage, key}] = std::string("run.") + key;
      }
    }
    k[{"track", "reference_frame"}] = "run.reference_frame";
    for (const char* stage : {"track", "triangulate", "stabilize", "jaw", "solve"}) {
      k[{stage, "markers"}] = "run.markers";
    }
    return k;
  }();
  return keys;
}

std::string RunSummary::BriefReport() const {
  std::vector<std::string> parts;
  for (const StageRun& s : stages) {
    if (s.status == "not run") continue;
    parts.push_back(s.status == "done" ? fmt::format("{} {:.1f} s", s.stage, s.seconds)
                                       : fmt::format("{} {}", s.stage, s.status));
  }
  return fmt::format("{} in {:.1f} s", fmt::join(parts, ", "), seconds);
}

namespace {

// One field of the header of `hmc solve --diagnostics` (docs/formats.md,
// "Solve diagnostics": one header field per line before the frames), read
// without parsing the frames, which a long shot makes large. null when the
// field is not there.
nlohmann::json DiagnosticsHeaderField(const fs::path& path, const std::string& name) {
  std::ifstream in(path);
  const std::string prefix = " \"" + name + "\": ";
  for (std::string line; std::getline(in, line);) {
    if (line.rfind(" \"frames\": ", 0) == 0) break;
    if (line.rfind(prefix, 0) != 0) continue;
    std::string value = line.substr(prefix.size());
    if (!value.empty() && value.back() == ',') value.pop_back();
    return nlohmann::json::parse(value, nullptr, /*allow_exceptions=*/false);
  }
  return nullptr;
}

// The run config: a mapping from stage name to that stage's options (the
// keys of configs/<stage>.yaml). Each section is handed to the stage's
// command as --config, and its canonical text is the stage's options key.
std::map<std::string, std::string> ReadRunConfig(const RunInput& input) {
  const std::string& file = input.config;
  std::map<std::string, std::string> sections;
  if (file.empty()) return sections;
  const YAML::Node root = LoadYamlFile(file);
  if (root.IsNull()) return sections;
  if (!root.IsMap()) ThrowInputError(file, 0, "a run config is a mapping from stage names to options");
  for (const auto& item : root) {
    const std::string stage = item.first.Scalar();
    if (stage == "run") continue;  // the run's own options (hmc run reads them)
    if (StageIndex(stage) < 0 || stage == "report") {
      ThrowInputError(file, item.first.Mark().line + 1, "unknown section '{}' (expected run or a stage: {})",
                      stage, "calibrate, track, triangulate, stabilize, jaw, solve");
    }
    if (sections.count(stage)) {
      ThrowInputError(file, item.first.Mark().line + 1, "stage '{}' given twice", stage);
    }
    if (!item.second.IsMap() && !item.second.IsNull()) {
      ThrowInputError(file, item.second.Mark().line + 1, "'{}' must be a mapping of options", stage);
    }
    for (const auto& option : item.second) {
      const auto moved = RunWideKeys().find({stage, option.first.Scalar()});
      if (moved != RunWideKeys().end()) {
        ThrowInputError(file, option.first.Mark().line + 1,
                        "'{}.{}' is set once for the whole run: give it as {} (or the flag --{})",
                        stage, option.first.Scalar(), moved->second, option.first.Scalar());
      }
    }
    if (input.check_section) input.check_section(stage, item.second, file);
    YAML::Emitter out;
    out << item.second;
    sections[stage] = std::string(out.c_str()) + "\n";
  }
  return sections;
}

// Everything one stage needs to run: what it depends on and how to run it.
struct StagePlan {
  StageKey key;
  std::string skip_reason;  // non-empty: the stage is not run (recorded)
  // Runs the stage's command(s) with outputs in `dir`; returns the stage's
  // report for summary.json.
  std::function<nlohmann::json(const fs::path& dir)> run;
};

class Pipeline {
 public:
  Pipeline(const RunInput& input, const RunOptions& options, const CommandRunner& run_command)
      : input_(input), options_(options), run_command_(run_command), work_(input.out, PipelineStages()) {}

  RunSummary Run();

 private:
  StagePlan Plan(const std::string& stage) const;
  // The stage's own command line, with --config for its section of the run
  // config (written into `dir`) when there is one.
  nlohmann::json RunCommand(const std::string& stage, std::vector<std::string> args,
                            const fs::path& dir) const;
  fs::path Out(const std::string& stage, const std::string& file) const {
    return work_.StageDir(stage) / file;
  }
  std::vector<std::string> FootageFlags() const;
  // Whether the run config's solve section sets robust.take.
  bool SolveSectionSetsTake() const {
    const auto section = config_.find("solve");
    if (section == config_.end()) return false;
    const YAML::Node solve = YAML::Load(section->second);
    return solve.IsMap() && solve["robust"] && solve["robust"].IsMap() && solve["robust"]["take"];
  }
  void AddFootageInputs(StageKey* key) const;
  // `--fps F` for the solve and the exports: the run's `fps` if set, else
  // the footage's frame rate (none for an image sequence, which declares
  // none: the commands' default); and `--timecode TC` for the exports when
  // cam0's video carries one (docs/formats.md, "Footage").
  struct FootageTiming {
    std::vector<std::string> fps;
    std::vector<std::string> timecode;
  };
  FootageTiming FootageTimingFlags() const;
  // `args` with `--markers DAY_MARKERS` when the run has the day's markers.
  std::vector<std::string> WithMarkers(std::vector<std::string> args) const {
    if (!options_.day.markers.empty()) args.insert(args.end(), {"--markers", options_.day.markers});
    return args;
  }

  RunInput input_;
  RunOptions options_;
  CommandRunner run_command_;
  Workspace work_;
  std::map<std::string, std::string> config_;
  std::string actor_hash_;
  bool actor_has_jaw_ = false;
  bool rig_has_tags_ = true;  // false: a tagless helmet, whose rig is used as it is
};

std::vector<std::string> Pipeline::FootageFlags() const {
  std::vector<std::string> flags;
  const FootageOptions& f = options_.footage;
  if (!f.cam0.empty()) flags.insert(flags.end(), {"--cam0", f.cam0});
  if (!f.cam1.empty()) flags.insert(flags.end(), {"--cam1", f.cam1});
  if (!f.frames.empty()) flags.insert(flags.end(), {"--frames", f.frames});
  if (f.offset1 != 0) flags.insert(flags.end(), {"--offset1", std::to_string(f.offset1)});
  return flags;
}

void Pipeline::AddFootageInputs(StageKey* key) const {
  // The footage as the reader finds it; names from the calibration.
  const FootageReader reader(input_.shot, ReadCalibration(input_.calibration).CameraNames(),
                             options_.footage);
  for (int c = 0; c < reader.num_cameras(); ++c) {
    key->AddInput("footage." + reader.camera_name(c), reader.source(c));
  }
  key->AddInputText("frames", options_.footage.frames);
  // Added only when set, so that a workspace run before these were run-wide
  // keeps its stages.
  if (options_.footage.offset1 != 0) {
    key->AddInputText("offset1", std::to_string(options_.footage.offset1));
  }
}

Pipeline::FootageTiming Pipeline::FootageTimingFlags() const {
  FootageTiming timing;
  const FootageReader reader(input_.shot, ReadCalibration(input_.calibration).CameraNames(),
                             options_.footage);
  const double fps = options_.fps > 0 ? options_.fps : reader.fps();
  // An image sequence: the commands' default rate.
  if (fps > 0) {
    timing.fps = {"--fps", fmt::format("{}", fps)};
  } else {
    spdlog::info("run: the footage (an image sequence) declares no frame rate: the mesh "
                 "caches play at 30 frames/s (set run.fps, --fps, for the camera's own)");
  }
  if (fs::is_regular_file(reader.source(0))) {
    const std::string timecode = ReadVideoTimecode(reader.source(0));
    if (!timecode.empty()) {
      spdlog::info("run: {} starts at timecode {}: the mesh caches that keep one carry it",
                   reader.source(0).string(), timecode);
      timing.timecode = {"--timecode", timecode};
    }
  }
  return timing;
}

nlohmann::json Pipeline::RunCommand(const std::string& stage, std::vector<std::string> args,
                                    const fs::path& dir) const {
  // The stage's section is its own command's options: `hmc convert`,
  // which the solve stage also runs, has none (and no --config).
  const auto section = config_.find(stage);
  if (section != config_.end() && args.front() == stage) {
    const fs::path config = dir / "run_config.yaml";
    WriteFileAtomic(config, section->second);
    args.insert(args.end(), {"--config", config.string()});
  }
  spdlog::info("run: hmc {}", fmt::join(args, " "));
  const int code = run_command_(args);
  if (code != 0) throw InputError(fmt::format("run: stage {} failed (exit code {})", stage, code));
  return nlohmann::json::object();
}

StagePlan Pipeline::Plan(const std::string& stage) const {
  StagePlan plan;
  plan.key.stage = stage;
  const auto section = config_.find(stage);
  plan.key.options = HashHex(HashBytes(section == config_.end() ? "" : section->second));
  StageKey& key = plan.key;
  const fs::path calibration = Out("calibrate", "calibration.yaml");
  if (stage == "calibrate") {
    key.AddInput("calibration", input_.calibration);
    const bool refine = options_.calibrate && rig_has_tags_;
    key.AddInputText("refine", refine ? "tags" : "none");
    if (!refine) {
      // A helmet without tags (most have none): the pair's own stereo
      // calibration is the rig, and the head's place in the helmet comes
      // from the footage (track registers it, stabilize fits it per frame;
      // docs/calibration.md, "A helmet without tags").
      const std::string why = options_.calibrate ? "the helmet has no tags: used as it is"
                                                 : "run.calibrate false: copied as it is";
      plan.run = [this, why](const fs::path& dir) {
        spdlog::info("calibrate: {}: {}", input_.calibration, why);
        WriteFileAtomic(dir / "calibration.yaml", ReadFile(input_.calibration));
        return nlohmann::json{{"calibration", "given (" + why + ")"}};
      };
      return plan;
    }
    AddFootageInputs(&key);
    plan.run = [this](const fs::path& dir) {
      std::vector<std::string> args = {"calibrate", "--shot", input_.shot, "--calibration",
                                       input_.calibration, "--out", (dir / "calibration.yaml").string(),
                                       "--report", (dir / "report.json").string()};
      const std::vector<std::string> footage = FootageFlags();
      args.insert(args.end(), footage.begin(), footage.end());
      return RunCommand("calibrate", args, dir);
    };
  } else if (stage == "track" && !input_.track_chunks.empty()) {
    // A take tracked in frame chunks (hmc batch --chunk-frames): their
    // tracks, each chunk's own frames, are the stage's (docs/farm.md).
    const std::vector<TrackChunk> chunks = ReadTrackChunks(input_.track_chunks);
    key.AddInput("track_chunks", input_.track_chunks);
    for (size_t i = 0; i < chunks.size(); ++i) {
      std::error_code ec;
      if (!fs::is_regular_file(ChunkTracks(chunks[i]), ec)) {
        ThrowInputError(ChunkTracks(chunks[i]), 0,
                        "chunk {} of the take (frames {}-{}) has no tracks: its task failed or "
                        "has not run (hmc batch runs it again)",
                        i, chunks[i].first, chunks[i].last);
      }
      key.AddInput(fmt::format("chunk{}.tracks", i), ChunkTracks(chunks[i]));
    }
    key.AddInput("calibration", calibration);
    key.AddInputText("actor", actor_hash_);
    plan.run = [chunks](const fs::path& dir) {
      MergeTrackChunks(chunks, dir);
      return nlohmann::json{{"merged_chunks", chunks.size()}};
    };
  } else if (stage == "track") {
    AddFootageInputs(&key);
    key.AddInput("calibration", calibration);
    key.AddInputText("actor", actor_hash_);
    if (options_.reference_frame > 0) {
      key.AddInputText("reference_frame", std::to_string(options_.reference_frame));
    }
    if (!input_.fixes.empty()) key.AddInput("fixes", input_.fixes);
    plan.run = [this, calibration](const fs::path& dir) {
      std::vector<std::string> args = {"track", "--shot", input_.shot, "--calibration",
                                       calibration.string(), "--actor", input_.actor, "--out",
                                       (dir / "tracks_2d.csv").string(), "--diagnostics",
                                       (dir / "diagnostics.json").string(),
                                       // hmc review's footage proxies, made as the footage is
                                       // decoded for the tracking (docs/review.md)
                                       "--proxies", (dir / "proxies").string()};
      const std::vector<std::string> footage = FootageFlags();
      args.insert(args.end(), footage.begin(), footage.end());
      if (options_.reference_frame > 0) {
        args.insert(args.end(), {"--reference_frame", std::to_string(options_.reference_frame)});
      }
      if (!input_.fixes.empty()) args.insert(args.end(), {"--fixes", input_.fixes});
      return RunCommand("track", WithMarkers(args), dir);
    };
  } else if (stage == "triangulate") {
    key.AddInput("tracks", Out("track", "tracks_2d.csv"));
    key.AddInput("calibration", calibration);
    key.AddInputText("actor", actor_hash_);
    // With the actor: the painted dots' offset under the skin is corrected
    // from its neutral's curvature (docs/calibration.md).
    plan.run = [this, calibration](const fs::path& dir) {
      return RunCommand("triangulate",
                        WithMarkers({"triangulate", "--tracks", Out("track", "tracks_2d.csv").string(),
                         "--calibration", calibration.string(), "--actor", input_.actor,
                         "--out", (dir / "bundles_helmet.csv").string(), "--diagnostics",
                         (dir / "triangulation.csv").string()}),
                        dir);
    };
  } else if (stage == "stabilize") {
    key.AddInput("bundles_helmet", Out("triangulate", "bundles_helmet.csv"));
    key.AddInputText("actor", actor_hash_);
    plan.run = [this](const fs::path& dir) {
      return RunCommand("stabilize",
                        WithMarkers({"stabilize", "--bundles", Out("triangulate", "bundles_helmet.csv").string(),
                         "--actor", input_.actor, "--out", dir.string()}),
                        dir);
    };
  } else if (stage == "jaw") {
    key.AddInput("bundles", Out("stabilize", "bundles.csv"));
    key.AddInputText("actor", actor_hash_);
    if (!actor_has_jaw_) {
      plan.skip_reason = "the actor has no jaw rig: the solve runs without jaw poses";
      return plan;
    }
    plan.run = [this](const fs::path& dir) {
      nlohmann::json report =
          RunCommand("jaw",
                     WithMarkers({"jaw", "--bundles", Out("stabilize", "bundles.csv").string(),
                                  "--actor", input_.actor, "--out", (dir / "jaw.csv").string()}),
                     dir);
      // hmc jaw names its summary after --out: it is the stage's, as a
      // summary.json of the command would be (workspace.h).
      const fs::path own = dir / "jaw_summary.json";
      if (fs::is_regular_file(own)) report["command_summary"] = nlohmann::json::parse(ReadFile(own));
      return report;
    };
  } else if (stage == "solve") {
    key.AddInput("bundles", Out("stabilize", "bundles.csv"));
    if (actor_has_jaw_) key.AddInput("jaw", Out("jaw", "jaw.csv"));
    // Markers seen by one camera constrain the solved mesh (docs/method.md,
    // "Constraints after the solve"), placed in head space by the head
    // poses.
    const bool rays = options_.rays && fs::is_regular_file(Out("triangulate", "rays.csv"));
    if (rays) {
      key.AddInput("rays", Out("triangulate", "rays.csv"));
      key.AddInput("head_from_helmet", Out("stabilize", "head_from_helmet.csv"));
      key.AddInput("calibration", calibration);
    }
    key.AddInputText("actor", actor_hash_);
    // The footage is one continuous recording: its frames are a take by
    // construction, so the solve's temporal steps run whatever the markers'
    // lag-1 correlation says of a short or quiet clip (issue 46, item 4:
    // a continuous 24-frame clip at 0.42 had them off, said only in the
    // info log), unless the run config's solve section decides
    // (robust.take; docs/method.md, "Takes").
    const bool take_given = SolveSectionSetsTake();
    if (!take_given) key.AddInputText("take", "footage");
    key.AddInputText("export", options_.export_formats);
    // Added only when not the default, so that a workspace solved before
    // the option existed keeps its solve stage.
    if (options_.diagnostics != "summary") key.AddInputText("diagnostics", options_.diagnostics);
    key.AddInputText("fps", fmt::format("{}", options_.fps));
    plan.run = [this, rays, calibration, take_given](const fs::path& dir) {
      std::vector<std::string> args = {"solve", "--actor", input_.actor, "--bundles",
                                       Out("stabilize", "bundles.csv").string(), "--out",
                                       (dir / "mesh.pc2").string(), "--diagnostics",
                                       (dir / "diagnostics.json").string(), "--diagnostics_detail",
                                       options_.diagnostics, "--topology",
                                       (dir / "neutral.obj").string()};
      if (actor_has_jaw_) args.insert(args.end(), {"--jaw", Out("jaw", "jaw.csv").string()});
      if (!take_given) args.insert(args.end(), {"--robust.take", "yes"});
      // The actor's units fitted to the solved meshes (docs/method.md,
      // "Animation curves"): the animators' controls; the USD rig with the
      // meshes' USD export.
      args.insert(args.end(), {"--weights", (dir / "weights.csv").string(), "--curves",
                               (dir / "curves.csv").string()});
      const std::vector<std::string> formats = ExportFormats(options_.export_formats);
      if (std::find(formats.begin(), formats.end(), "usda") != formats.end()) {
        args.insert(args.end(), {"--unit_rig", (dir / "unit_rig.usda").string()});
      }
      if (rays) {
        args.insert(args.end(), {"--rays", Out("triangulate", "rays.csv").string(),
                                 "--head_from_helmet",
                                 Out("stabilize", "head_from_helmet.csv").string(),
                                 "--calibration", calibration.string()});
      }
      args = WithMarkers(args);
      // The footage's frame rate, so that the exports play at the shot's
      // speed (a 60 fps helmet camera's mesh is not written at 30).
      const FootageTiming timing = FootageTimingFlags();
      args.insert(args.end(), timing.fps.begin(), timing.fps.end());
      nlohmann::json report = RunCommand("solve", args, dir);
      if (rays) report["rays"] = DiagnosticsHeaderField(dir / "diagnostics.json", "rays");
      report["unit_fit"] = DiagnosticsHeaderField(dir / "diagnostics.json", "unit_fit");
      // Whether the temporal steps ran, in the summary, and as a warning
      // of the report (and the day report) when they did not.
      const nlohmann::json method = DiagnosticsHeaderField(dir / "diagnostics.json", "report");
      if (method.is_object() && method.contains("take")) {
        const double correlation = method.value("take_correlation", 0.0);
        report["take"] = {{"take", method.value("take", 0.0) == 1.0},
                          {"lag1_correlation", correlation}};
        if (method.value("take", 0.0) != 1.0) {
          report["warnings"] = {fmt::format(
              "the frames were not treated as a take (the markers' lag-1 correlation {:.2f}, "
              "robust.take as the run config sets it): the temporal steps (3b, 3c and step 5's "
              "averaging) were off; for a continuous clip set robust: take: yes",
              correlation)};
        }
      }
      for (const std::string& format : ExportFormats(options_.export_formats)) {
        const fs::path target = dir / (format == "obj" ? "mesh_obj" : "mesh." + format);
        std::vector<std::string> convert = {"convert", (dir / "mesh.pc2").string(),
                                            target.string(), "--topology",
                                            (dir / "neutral.obj").string()};
        // An image sequence's caches at the commands' default rate, said
        // once here rather than as a warning of every export.
        const std::vector<std::string> fps =
            timing.fps.empty() ? std::vector<std::string>{"--fps", "30"} : timing.fps;
        convert.insert(convert.end(), fps.begin(), fps.end());
        convert.insert(convert.end(), timing.timecode.begin(), timing.timecode.end());
        RunCommand("solve", convert, dir);
      }
      return report;
    };
  } else if (stage == "report") {
    for (const std::string& s : PipelineStages()) {
      if (s == "report") continue;
      const nlohmann::json summary = work_.ReadSummary(s);
      key.AddInputText(s, summary.is_object() ? summary["key"].dump() : "");
    }
    plan.run = [this](const fs::path& dir) {
      return RunCommand("report",
                        {"report", "--work", work_.root().string(), "--shot", input_.shot,
                         "--actor", input_.actor, "--out", dir.string()},
                        dir);
    };
  }
  return plan;
}

RunSummary Pipeline::Run() {
  const auto start = std::chrono::steady_clock::now();
  config_ = ReadRunConfig(input_);
  // The user's calibration is checked here, so that what is wrong with it
  // names that file, not the workspace's copy a later stage reads.
  const HelmetRig rig = ReadCalibration(input_.calibration);
  if (rig.cameras.size() != 2) {
    ThrowInputError(input_.calibration, 0, "hmc run needs a rig of two cameras, the file has {}",
                    rig.cameras.size());
  }
  // With the day's markers, the actor's hash is theirs too: every stage that
  // reads the actor runs again for another marker set.
  const std::shared_ptr<const Actor> loaded = LoadActorForDay(input_.actor, options_.day.markers);
  const Actor& actor = *loaded;
  actor_hash_ = HashHex(actor.content_hash);
  actor_has_jaw_ = actor.jaw_rig.has_value();
  rig_has_tags_ = !rig.tags.empty();
  const int last = StageIndex(options_.to);
  const int forced = options_.from.empty() ? INT32_MAX : StageIndex(options_.from);
  RunSummary summary;
  for (int i = 0; i < static_cast<int>(PipelineStages().size()); ++i) {
    const std::string& stage = PipelineStages()[i];
    StageRun run{stage, "not run", "", 0};
    if (i > last) {
      summary.stages.push_back(run);
      continue;
    }
    work_.CheckStillThere();  // before the stage's inputs in it are hashed
    const StagePlan plan = Plan(stage);
    if (i < forced && work_.IsComplete(plan.key)) {
      spdlog::info("run: {} complete (inputs and options unchanged): kept", stage);
      run.status = "complete";
      summary.stages.push_back(run);
      continue;
    }
    const auto stage_start = std::chrono::steady_clock::now();
    if (!plan.skip_reason.empty()) {
      spdlog::info("run: {} skipped: {}", stage, plan.skip_reason);
      work_.RunStage(plan.key, [&](const fs::path&) {
        return nlohmann::json{{"skipped", plan.skip_reason}};
      });
      run.status = "skipped";
      run.note = plan.skip_reason;
    } else {
      // Each stage's report names the run's inputs, so that `hmc review
      // --work WORK` finds the footage and the actor (docs/formats.md,
      // "Shot workspace").
      work_.RunStage(plan.key, [&](const fs::path& dir) {
        nlohmann::json report = plan.run(dir);
        report["run_inputs"] = {{"shot", fs::absolute(input_.shot).lexically_normal().string()},
                                {"actor", fs::absolute(input_.actor).lexically_normal().string()}};
        return report;
      });
      run.status = "done";
    }
    ReturnFreedMemory();
    run.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - stage_start).count();
    summary.stages.push_back(run);
  }
  summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return summary;
}

}  // namespace

RunSummary RunPipeline(const RunInput& input, const RunOptions& options,
                       const CommandRunner& run_command) {
  return Pipeline(input, options, run_command).Run();
}

}  // namespace hmc
