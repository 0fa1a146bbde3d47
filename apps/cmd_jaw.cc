// `hmc jaw --bundles bundles.csv --actor DIR --out jaw.csv
//   [--config configs/jaw.yaml] [--truth FILE]`: the jaw pose per frame from head-space
// bundles with the actor's jaw rig (stabilization/jaw_fit.h). Writes
// jaw.csv and, beside it, jaw_options_used.yaml and jaw_summary.json
// (docs/formats.md; method: docs/stabilization.md).
#include <memory>
#include <string>

#include <spdlog/spdlog.h>

#include "apps/command.h"
#include "core/day_markers.h"
#include "core/actor.h"
#include "core/actor_cache.h"
#include "core/frame_data.h"
#include "core/frame_gaps.h"
#include "core/logging.h"
#include "stabilization/accuracy.h"
#include "stabilization/jaw_fit.h"
#include "stabilization/marker_model.h"

namespace hmc {

HMC_COMMAND(Jaw, "", "jaw",
            "Estimate the jaw pose per frame from head-space bundles with the actor's jaw "
            "rig") {
  auto options = std::make_shared<JawOptions>();
  auto binding = BindOptions(app, options.get());
  auto bundles = std::make_shared<std::string>();
  auto actor_dir = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  auto truth = std::make_shared<std::string>();
  app->add_option("--bundles", *bundles, "bundles.csv: bundles in head space (hmc stabilize)")
      ->required();
  app->add_option("--actor", *actor_dir, "Actor package (with a jaw rig)")->required();
  app->add_option("--out", *out, "jaw.csv to write")->required();
  app->add_option("--truth", *truth,
                  "Optional true jaw.csv (synthetic shots): log the jaw error");
  return [=] {
    binding->Apply();
    RequireValid(*options, "jaw");
    // Beside jaw.csv, named after its stem (WriteJawOutput).
    const std::filesystem::path out_path(*out);
    const std::filesystem::path stem = out_path.parent_path() / out_path.stem();
    PrepareOutputPaths({{out_path, "--out"},
                        SideFile(stem.string() + "_options_used.yaml", "jaw"),
                        SideFile(stem.string() + "_summary.json", "jaw")},
                       {{*bundles, "--bundles"}, {*actor_dir, "--actor"}, {*truth, "--truth"}});
    StageTimer timer("jaw");
    const std::shared_ptr<const Actor> loaded = LoadActorForDay(*actor_dir, options->day.markers);
    const Actor& actor = *loaded;
    std::vector<BundleFrame> frames = ReadBundlesCsv(*bundles);
    // A frame lost upstream is fitted as a bad frame: interpolated, flagged.
    const std::vector<int> missing = InsertMissingFrames(&frames, *bundles);
    const MarkerModel model = ComputeMarkerModel(actor);
    JawOutput output = RunJaw(actor, model, frames, *options);
    MarkMissingFrames(missing, &output.frames);
    WriteJawOutput(output, *options, *out);
    spdlog::info("jaw: {} -> {}", output.BriefReport(), *out);
    if (!truth->empty()) {
      spdlog::info("jaw: {}", CompareJaw(output.JawFrames(), ReadJawCsv(*truth)).BriefReport());
    }
    return 0;
  };
}

}  // namespace hmc
