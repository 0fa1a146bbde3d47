// `hmc actor synth --out DIR [--seed N] [--rig generator|linear|broad]
// [--holdout N] [--config FILE]`:
// writes the synthetic actor package (docs/synthetic.md; how it is made:
// docs/synthetic.md). Besides the package files of WriteActor it writes
//   synth.yaml               the generator options used (with the seed and
//                            the held-out units resolved to their names), so
//                            `hmc actor frames` can regenerate the model
//   dataset_activations.csv  shape,<one column per unit>: what built each shape
#include <memory>
#include <sstream>
#include <string>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "apps/command.h"
#include "core/actor.h"
#include "core/file_util.h"
#include "core/logging.h"
#include "synth/face_model.h"
#include "synth/synth_actor.h"

namespace hmc {
namespace {

void WriteDatasetActivations(const std::filesystem::path& path,
                             const FaceModel& model,
                             const std::vector<DatasetEntry>& plan) {
  WriteFileAtomic(path, [&](std::ostream& out) {
    out << "shape";
    for (const ActionUnit& unit : model.units()) out << ',' << unit.name;
    out << '\n';
    for (const DatasetEntry& entry : plan) {
      out << entry.name;
      for (int k = 0; k < entry.activations.size(); ++k) {
        out << ',' << fmt::format("{:.6g}", entry.activations[k]);
      }
      out << '\n';
    }
  });
}

}  // namespace

HMC_COMMAND(ActorSynth, "actor", "synth",
            "Write the synthetic actor package: procedural face, markers, jaw "
            "rig, action-unit dataset") {
  auto options = std::make_shared<SynthActorOptions>();
  auto binding = BindOptions(app, options.get());
  auto out = std::make_shared<std::string>();
  app->add_option("--out", *out, "Output actor package folder")->required();
  return [=] {
    binding->Apply();
    RequireValid(*options, "actor synth");
    StageTimer timer("actor synth");
    // Written whole (docs/reliability.md).
    WriteFolderAtomic(*out, "hmc actor synth", [&](const std::filesystem::path& dir) {
      Actor actor;
      std::vector<DatasetEntry> plan;
      {
        StageTimer generate("generate");
        const FaceModel model(*options);
        // synth.yaml records the held-out names, not only their count.
        *options = ResolveHoldout(model, *options);
        plan = PlanDataset(model, *options);
        actor = SynthesizeActorFromModel(model, *options);
        spdlog::info(
            "actor synth: seed {}, {} vertices, {} triangles, {} markers, {} "
            "units, {} shapes",
            options->seed, actor.NumVertices(), actor.neutral.NumFaces(),
            actor.markers.size(), model.NumUnits(), actor.shapes.size());
        if (options->holdout > 0) {
          spdlog::info("actor synth: {} units held out of the dataset: {}",
                       options->holdout, options->holdout_units);
        }
        WriteDatasetActivations(dir / "dataset_activations.csv", model, plan);
      }
      {
        StageTimer write("write package");
        WriteActor(actor, dir);
        WriteSynthActorOptions(*options, dir);
      }
    });
    spdlog::info("actor synth: wrote {}", *out);
    return 0;
  };
}

}  // namespace hmc
