// `hmc experiment --actor DIR --out DIR [--seed N] [--config FILE]`: the
// side-by-side comparison of every solve method on held-out material from
// the synthetic actor's generator (eval/experiment.h; docs/baselines.md).
// Writes to --out the table (results.md, results.json), each material's
// files, pictures and options_used.yaml (docs/formats.md, "hmc experiment
// outputs").
#include <memory>
#include <string>

#include <spdlog/spdlog.h>

#include "apps/command.h"
#include "core/file_util.h"
#include "eval/experiment.h"

namespace hmc {

HMC_COMMAND(Experiment, "", "experiment",
            "Compare every solve method on held-out synthetic material "
            "(table, JSON, pictures)") {
  auto input = std::make_shared<ExperimentInput>();
  auto options = std::make_shared<ExperimentOptions>();
  auto actor_dir = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  app->add_option("--actor", *actor_dir,
                  "Synthetic actor package (from `hmc actor synth`)")
      ->required()
      ->check(CLI::ExistingDirectory);
  app->add_option("--out", *out, "Output folder")->required();
  app->add_option("--seed", input->seed,
                  "Seed of the material's activations and marker noise");
  auto binding = BindOptions(app, options.get());
  return [=] {
    binding->Apply();
    input->actor_dir = *actor_dir;
    PrepareOutputPaths({{*out, "--out", true}}, {{*actor_dir, "--actor"}});
    // Written whole: a re-run with fewer kinds or noise levels leaves none
    // of the earlier run's folders behind (docs/reliability.md).
    ExperimentOutput output;
    WriteFolderAtomic(*out, "hmc experiment", [&](const std::filesystem::path& dir) {
      input->out = dir;
      output = RunExperiment(*input, *options);
      WriteOptionsUsed(binding->fields(), dir / "options_used.yaml", "experiment");
    });
    spdlog::info("experiment: {} -> {}", output.BriefReport(),
                 (std::filesystem::path(*out) / "results.md").string());
    return 0;
  };
}

}  // namespace hmc
