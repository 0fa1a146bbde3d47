// `hmc actor frames --actor DIR --out DIR
//   --kind dataset|combos|performance|heldout|mixed [--frames N] [--seed N]
//   [--noise_mm S]`: ground-truth test material from the synthetic actor's
// generator (docs/synthetic.md). heldout and mixed need an actor made with
// held-out units (`hmc actor synth --holdout N`). --noise_mm applies to every
// kind. Writes to --out:
//   truth.pc2        the true mesh sequence (frames numbered from 1, --fps)
//   neutral.obj      its topology (the package's neutral)
//   bundles.csv      every marker's surface point on the truth, + noise
//   jaw.csv          the true jaw pose per frame
//   activations.csv  frame,<one column per unit>
//   labels.csv       frame,label (the shape name for --kind dataset)
//   options_used.yaml
// The generator is rebuilt from the package's synth.yaml and checked against
// the package's neutral, so an edited or stale package is refused.
#include <memory>
#include <string>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "apps/command.h"
#include "core/actor.h"
#include "core/file_util.h"
#include "core/frame_data.h"
#include "core/logging.h"
#include "core/mesh_sequence.h"
#include "core/obj_io.h"
#include "synth/face_model.h"
#include "synth/synth_actor.h"
#include "synth/truth_frames.h"

namespace hmc {
namespace {

void WritePerFrameCsv(const std::filesystem::path& path, const std::string& header,
                      const TruthFrames& frames,
                      const std::function<std::string(int)>& row) {
  WriteFileAtomic(path, [&](std::ostream& out) {
    out << header << '\n';
    for (size_t f = 0; f < frames.positions.size(); ++f) {
      out << frames.start_frame + static_cast<int>(f) << ',' << row(static_cast<int>(f))
          << '\n';
    }
  });
}

}  // namespace

HMC_COMMAND(ActorFrames, "actor", "frames",
            "Write ground-truth frames of a synthetic actor (truth mesh "
            "sequence, bundles, jaw, activations)") {
  auto options = std::make_shared<TruthFramesOptions>();
  auto binding = BindOptions(app, options.get());
  auto actor_dir = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  app->add_option("--actor", *actor_dir, "Synthetic actor package (from `hmc actor synth`)")
      ->required();
  app->add_option("--out", *out, "Output folder")->required();
  return [=] {
    binding->Apply();
    RequireValid(*options, "actor frames");
    StageTimer timer("actor frames");
    const SynthPackage package = LoadSynthPackage(*actor_dir);
    const SynthActorOptions& synth = package.options;
    const Actor& actor = package.actor;
    const FaceModel& model = *package.model;
    const std::filesystem::path& synth_file = package.synth_file;
    const std::vector<int> held = HeldOutUnits(model, synth, synth_file);
    if (KindNeedsHeldOutUnits(options->kind) && held.empty()) {
      ThrowInputError(synth_file, 0,
                      "--kind {} needs held-out units, but this actor holds "
                      "none out (holdout: 0); make one with `hmc actor synth "
                      "--holdout N`",
                      options->kind);
    }
    const std::vector<DatasetEntry> plan = PlanDataset(model, synth);
    // heldout and mixed mean "units the package's dataset lacks": its shapes
    // must be exactly the plan's, so no shape uses a held-out unit.
    if (KindNeedsHeldOutUnits(options->kind) && actor.shapes.size() != plan.size()) {
      ThrowInputError(actor.dir / "actor.yaml", 0,
                      "the package has {} shapes but synth.yaml's generator "
                      "makes {}: the package was edited or is stale",
                      actor.shapes.size(), plan.size());
    }
    if (options->kind == "dataset" || KindNeedsHeldOutUnits(options->kind)) {
      for (const DatasetEntry& entry : plan) {
        if (actor.FindShape(entry.name) < 0) {
          ThrowInputError(actor.dir / "actor.yaml", 0,
                          "the package has no shape '{}' that synth.yaml's "
                          "generator makes: the package was edited or is stale",
                          entry.name);
        }
      }
    }
    TruthFrames frames;
    {
      StageTimer evaluate("evaluate frames");
      frames = MakeTruthFrames(model, actor.markers, plan, *options);
    }
    // Written whole (docs/reliability.md).
    WriteFolderAtomic(*out, "hmc actor frames", [&](const std::filesystem::path& dir) {
      MeshSequence sequence;
      sequence.frames = frames.positions;
      sequence.start_frame = frames.start_frame;
      sequence.fps = options->fps;
      sequence.topology = actor.neutral;
      WriteMeshSequence(dir / "truth.pc2", sequence);
      WriteObj(dir / "neutral.obj", actor.neutral);
      WriteBundlesCsv(dir / "bundles.csv", frames.bundles);
      WriteJawCsv(dir / "jaw.csv", frames.jaw);
      std::string header = "frame";
      for (const ActionUnit& unit : model.units()) header += "," + unit.name;
      WritePerFrameCsv(dir / "activations.csv", header, frames, [&](int f) {
        std::string row;
        for (int k = 0; k < frames.activations[f].size(); ++k) {
          row += fmt::format("{}{:.6g}", k ? "," : "", frames.activations[f][k]);
        }
        return row;
      });
      WritePerFrameCsv(dir / "labels.csv", "frame,label", frames,
                       [&](int f) { return frames.labels[f]; });
      OptionFields used;
      options->Register(&used);
      WriteOptionsUsed(used, dir / "options_used.yaml", "actor frames");
    });
    if (!held.empty()) {
      spdlog::info("actor frames: {} held-out units: {}", held.size(),
                   synth.holdout_units.empty() ? "(drawn from the seed)"
                                               : synth.holdout_units);
    }
    spdlog::info("actor frames: {} {} frames of {} markers (noise {} mm) -> {}",
                 frames.positions.size(), options->kind, actor.markers.size(),
                 options->noise_mm, *out);
    return 0;
  };
}

}  // namespace hmc
