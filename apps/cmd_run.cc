// `hmc run --shot SHOT --actor DIR --calibration CAL --out WORK [--from
// STAGE] [--to STAGE] [--frames A:B] [--config FILE]`: footage to mesh in
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
  app->add_option("--shot", input->shot, "Shot folder: cam0/cam1 videos or image folders")
      ->required();
  app->add_option("--actor", input->actor, "Actor package folder")->required();
  app->add_option("--calibration", input->calibration,
                  "calibration.yaml: the nominal rig (refined from the helmet tags unless "
                  "--calibrate false)")
      ->required();
  app->add_option("--out", input->out, "Workspace folder (one sub-folder per stage)")->required();
  OptionFields fields;
  options->Register(&fields);
  // --config: the run config (configs/run.yaml): `run:` holds these
  // options, one section per stage holds that stage's.
  auto binding = std::make_shared<OptionBinding>(app, std::move(fields), "run");
  return [=] {
    binding->Apply();
    input->config = binding->config_file();
    RequireValid(*options, "run");
    PrepareOutputPaths({{input->out, "--out", true}},
                       {{input->shot, "--shot"},
                        {input->actor, "--actor"},
                        {input->calibration, "--calibration"},
                        {input->config, "--config"}});
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
