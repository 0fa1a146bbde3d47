// `hmc synth shot --actor DIR --out SHOT [--frames N] [--seed N]
//   [--config FILE]`: synthetic stereo helmet-camera footage of a synthetic
// actor with exact ground truth (synth/footage_shot.h). Writes to SHOT the
// videos (cam0.mkv, cam1.mkv, or PNG folders), calibration.yaml, the ground
// truth (dots_2d.csv, tags_2d.csv, bundles.csv, bundles_helmet.csv,
// head_from_helmet.csv, jaw.csv, truth.pc2 + neutral.obj), contact_sheet.png
// and options_used.yaml (docs/formats.md, "Shot folder"). SHOT is written
// whole (a temporary folder renamed at the end); a non-empty folder that
// `hmc synth shot` did not write, or one inside an actor package, is
// refused.
#include <memory>
#include <string>

#include <spdlog/spdlog.h>

#include "apps/command.h"
#include "core/actor.h"
#include "core/file_util.h"
#include "core/logging.h"
#include "synth/face_model.h"
#include "synth/footage_shot.h"
#include "synth/synth_actor.h"

namespace hmc {

HMC_COMMAND(SynthShot, "synth", "shot",
            "Render synthetic stereo helmet-camera footage of a synthetic actor "
            "with exact ground truth") {
  auto options = std::make_shared<SynthShotOptions>();
  auto binding = BindOptions(app, options.get());
  auto actor_dir = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  app->add_option("--actor", *actor_dir, "Synthetic actor package (from `hmc actor synth`)")
      ->required();
  app->add_option("--out", *out, "Shot folder to write")->required();
  return [=] {
    binding->Apply();
    RequireValid(*options, "synth shot");
    StageTimer timer("synth shot");
    const SynthPackage package = LoadSynthPackage(*actor_dir);
    // Written whole: a re-run never leaves an earlier run's files behind
    // (docs/reliability.md).
    SynthShotSummary summary;
    WriteFolderAtomic(*out, "hmc synth shot", [&](const std::filesystem::path& dir) {
      summary = RunSynthShot(*package.model, package.actor, *options, dir);
    });
    spdlog::info("synth shot: {} -> {}", summary.BriefReport(), *out);
    return 0;
  };
}

}  // namespace hmc
