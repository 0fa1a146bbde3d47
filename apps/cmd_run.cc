// `hmc run --shot SHOT --actor DIR --calibration CAL --out WORK [--cam0 V]
// [--cam1 V] [--offset1 N] [--frames A:B] [--reference_frame N] [--fps F]
// [--from STAGE] [--to STAGE] [--fixes track_fixes.csv] [--config FILE]`: footage to mesh in
// one command (pipeline/run_pipeline.h, docs/pipeline.md). Each stage runs
// as its own hmc command on the previous stage's folder of WORK, so any
// stage can be re-run alone; complete stages are kept.
#include <memory>
#include <string>

#include <spdlog/spdlog.h>

#include "apps/command.h"
#include "core/actor_cache.h"
#include "core/logging.h"
#include "pipeline/run_pipeline.h"

namespace hmc {

HMC_COMMAND(Run, "", "run",
            "Footage to mesh: calibrate, track, triangulate, stabilize, jaw, solve and "
            "report in a shot workspace, keeping the stages that are complete") {
  auto input = std::make_shared<RunInput>();
  auto options = std::make_shared<RunOptions>();
  const std::string data = "Your data (required)";
  app->add_option("--shot", input->shot, "Shot folder: cam0/cam1 videos or image folders")
      ->required()
      ->group(data);
  app->add_option("--actor", input->actor, "Actor package folder (hmc actor check validates one)")
      ->required()
      ->group(data);
  app->add_option("--calibration", input->calibration,
                  "calibration.yaml: the nominal rig (refined from the helmet tags unless "
                  "--calibrate false; hmc calibrate --import_kalibr takes a Kalibr camchain)")
      ->required()
      ->group(data);
  app->add_option("--out", input->out, "Workspace folder (one sub-folder per stage)")
      ->required()
      ->group(data);
  app->add_option("--fixes", input->fixes,
                  "track_fixes.csv from hmc review: the track stage applies them (with --from "
                  "track, every later stage is redone)")
      ->group(data);
  app->add_option("--track_chunks", input->track_chunks,
                  "The take's frame chunks tracked apart (written by hmc batch --chunk-frames; "
                  "docs/farm.md): the track stage merges their own frames instead of tracking")
      ->group(data);
  OptionFields fields;
  options->Register(&fields);
  // --config: the run config (configs/run.yaml): `run:` holds these
  // options, one section per stage holds that stage's.
  auto binding = std::make_shared<OptionBinding>(app, std::move(fields), "run");
  // Grouped as a user meets them with their own footage (the flags are the
  // binding's; only their heading is chosen here).
  for (const char* flag : {"--cam0", "--cam1", "--offset1", "--frames", "--reference_frame", "--fps"}) {
    app->get_option(flag)->group("Footage, set once for every stage (also run: in --config)");
  }
  for (const char* flag : {"--calibrate", "--export", "--diagnostics", "--from", "--to"}) {
    app->get_option(flag)->group("The run (also run: in --config)");
  }
  app->footer(
      "--config FILE (configs/run.yaml) holds run: (the flags above) and one section per stage "
      "(calibrate, track, triangulate, stabilize, jaw, solve) with that stage's options; "
      "every section is checked before the first stage runs.");
  // Every stage's section is checked as that stage's own command reads
  // its --config, before the first stage runs.
  input->check_section = [](const std::string& stage, const YAML::Node& section,
                            const std::filesystem::path& file) {
    CheckCommandConfig({stage}, section, file);
  };
  return [=] {
    binding->Apply();
    input->config = binding->config_file();
    RequireValid(*options, "run");
    PrepareOutputPaths({{input->out, "--out", true}},
                       {{input->shot, "--shot"},
                        {input->actor, "--actor"},
                        {input->calibration, "--calibration"},
                        {input->config, "--config"},
                        {input->fixes, "--fixes"},
                        {input->track_chunks, "--track_chunks"}});
    StageTimer timer("run");
    // Every stage loads the actor; parse it once for the run (each stage
    // still reads and hashes the files: core/actor_cache.h).
    struct ActorCacheOn {
      ActorCacheOn() { EnableActorCache(true); }
      ~ActorCacheOn() { EnableActorCache(false); }
    } cache;
    const RunSummary summary = RunPipeline(*input, *options, &RunCommandLine);
    spdlog::info("run: {} -> {}", summary.BriefReport(), input->out);
    return 0;
  };
}

}  // namespace hmc
