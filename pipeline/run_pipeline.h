// `hmc run`: footage to mesh in one command (docs/pipeline.md). Chains the
// stages calibrate -> track -> triangulate -> stabilize -> jaw -> solve ->
// report, each run as its own `hmc` command on the files the previous stage
// wrote, in the shot workspace (pipeline/workspace.h): so a stage's folder
// holds exactly what its own command writes, any stage can be re-run alone
// on the folder before it, and a complete stage is not redone.
#pragma once

#include <filesystem>
#include <functional>
#include <map>
#include <utility>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/day_markers.h"
#include "core/options.h"
#include "tracking/footage_reader.h"

namespace hmc {

// The stages, in order; also the workspace's folder names.
const std::vector<std::string>& PipelineStages();

// What a user sets once for the whole run (`run:` of the run config, or
// flags): the footage's cameras and frames, which every stage that reads
// footage shares (docs/pipeline.md, "Options set once for the run").
struct RunOptions {
  std::string from;         // first stage to redo even if complete ("" = none forced)
  std::string to = "report";  // last stage to run
  // cam0, cam1 (video or image folder), frames (A:B), offset1 (cam1's frame
  // offset): passed to calibrate and track; not keys of their sections.
  FootageOptions footage;
  int reference_frame = 0;  // frame where the actor is near neutral, for track (0 = track's own default)
  bool calibrate = true;    // refine the rig from the helmet tags; false: use --calibration as it is
  // Mesh formats written beside solve/mesh.pc2: usda, mdd, obj
  // (comma-separated; "" = none). None by default: mesh.pc2 (float32, the
  // compact one) is always written; ASCII USDA is ~3x its size (issue 46).
  std::string export_formats;
  std::string diagnostics = "summary";  // solve/diagnostics.json: summary (per frame and observed bundle) or full (every bundle's shapes and weights)
  DayMarkersOptions day;    // markers: the day's markers, passed to every stage that loads the actor
  bool rays = false;        // the solve uses triangulate's rays.csv (markers seen by one camera; docs/method.md, "Constraints after the solve")
  double fps = 0;           // frame rate of the mesh caches (frames/s; 0 = the video's own, or the commands' 30 for an image sequence, which declares none)

  void Register(OptionFields* fields);
  bool Check() const;
};

// The keys a stage's section of the run config may not hold because the
// run sets them once (`run:`): {stage, key} -> where it moved ("run.offset1").
const std::map<std::pair<std::string, std::string>, std::string>& RunWideKeys();

struct RunInput {
  std::string shot;         // shot folder (footage, optional ground truth)
  std::string actor;        // actor package
  std::string calibration;  // nominal calibration.yaml (or the rig's calibration)
  std::string out;          // workspace folder WORK
  std::string fixes;        // track_fixes.csv for the track stage (hmc review; "" = none)
  // The take's frame chunks, tracked apart (pipeline/track_chunks.h, written
  // by hmc batch --chunk-frames): the track stage merges their tracks
  // instead of tracking ("" = track the footage).
  std::string track_chunks;
  std::string config;       // run config: `run:` (RunOptions, read by hmc run) and a section per stage with that stage's options ("" = defaults)
  // Checks one stage's section of `config` as that stage's command would
  // read it (keys, types, ranges; throws InputError naming the file and
  // line). hmc run checks every section with it before the first stage
  // runs; empty: sections are checked by the stages themselves.
  std::function<void(const std::string& stage, const YAML::Node& section,
                     const std::filesystem::path& file)>
      check_section;
};

// Runs one `hmc` command line in this process (args without the program
// name: {"track", "--shot", ...}); returns its exit code, throws what the
// command throws.
using CommandRunner = std::function<int(const std::vector<std::string>& args)>;

struct StageRun {
  std::string stage;
  std::string status;  // "done", "complete" (skipped: inputs and options unchanged), "skipped" (why in note), "not run"
  std::string note;
  double seconds = 0;
};

struct RunSummary {
  std::vector<StageRun> stages;
  double seconds = 0;
  std::string BriefReport() const;
};

// Throws InputError for bad input (naming the file) and when a stage's
// command fails (naming the stage; what it wrote is kept only if it had
// completed).
RunSummary RunPipeline(const RunInput& input, const RunOptions& options,
                       const CommandRunner& run_command);

}  // namespace hmc
