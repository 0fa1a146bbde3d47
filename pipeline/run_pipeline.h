// `hmc run`: footage to mesh in one command (docs/pipeline.md). Chains the
// stages calibrate -> track -> triangulate -> stabilize -> jaw -> solve ->
// report, each run as its own `hmc` command on the files the previous stage
// wrote, in the shot workspace (pipeline/workspace.h): so a stage's folder
// holds exactly what its own command writes, any stage can be re-run alone
// on the folder before it, and a complete stage is not redone.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/options.h"

namespace hmc {

// The stages, in order; also the workspace's folder names.
const std::vector<std::string>& PipelineStages();

struct RunOptions {
  std::string from;         // first stage to redo even if complete ("" = none forced)
  std::string to = "report";  // last stage to run
  std::string frames;       // frame range A:B of the footage ("" = all)
  bool calibrate = true;    // refine the rig from the helmet tags; false: use --calibration as it is
  std::string export_formats = "usda";  // mesh formats written beside solve/mesh.pc2: usda, mdd, obj (comma-separated; "" = none)
  double fps = 0;           // frame rate of the mesh caches (frames/s; 0 = the video's own, or the commands' 30 for an image sequence, which declares none)

  void Register(OptionFields* fields);
  bool Check() const;
};

struct RunInput {
  std::string shot;         // shot folder (footage, optional ground truth)
  std::string actor;        // actor package
  std::string calibration;  // nominal calibration.yaml (or the rig's calibration)
  std::string out;          // workspace folder WORK
  std::string config;       // run config: `run:` (RunOptions, read by hmc run) and a section per stage with that stage's options ("" = defaults)
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
