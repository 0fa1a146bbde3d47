// `hmc stabilize --bundles bundles_helmet.csv --actor DIR --out DIR
//   [--config configs/stabilize.yaml] [--truth FILE]`: the rigid head pose per frame and
// the bundles in head space (stabilization/stabilize.h). Writes to DIR
// head_from_helmet.csv, bundles.csv, residuals.csv, options_used.yaml and
// summary.json (docs/formats.md; method: docs/stabilization.md).
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
#include "stabilization/marker_model.h"
#include "stabilization/stabilize.h"

namespace hmc {

HMC_COMMAND(Stabilize, "", "stabilize",
            "Estimate the head pose in the helmet per frame and write the bundles in "
            "head space") {
  auto options = std::make_shared<StabilizeOptions>();
  auto binding = BindOptions(app, options.get());
  auto bundles = std::make_shared<std::string>();
  auto actor_dir = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  auto truth = std::make_shared<std::string>();
  app->add_option("--bundles", *bundles, "bundles_helmet.csv: bundles in helmet space")
      ->required();
  app->add_option("--actor", *actor_dir, "Actor package")->required();
  app->add_option("--out", *out, "Folder to write")->required();
  app->add_option("--truth", *truth,
                  "Optional true head_from_helmet.csv (synthetic shots): log the pose error");
  return [=] {
    binding->Apply();
    RequireValid(*options, "stabilize");
    const std::filesystem::path out_dir(*out);
    PrepareOutputPaths({{out_dir, "--out", true},
                        {out_dir / "options_used.yaml", "options_used.yaml in --out", false,
                         "stabilize"},
                        {out_dir / "summary.json", "summary.json in --out", false, "stabilize"}},
                       {{*bundles, "--bundles"}, {*actor_dir, "--actor"}, {*truth, "--truth"}});
    StageTimer timer("stabilize");
    const std::shared_ptr<const Actor> loaded = LoadActorForDay(*actor_dir, options->day.markers);
    const Actor& actor = *loaded;
    std::vector<BundleFrame> frames = ReadBundlesCsv(*bundles);
    // A frame lost upstream is fitted as a bad frame: interpolated, flagged.
    const std::vector<int> missing = InsertMissingFrames(&frames, *bundles);
    const MarkerModel model = ComputeMarkerModel(actor);
    StabilizeOutput output = RunStabilize(model, frames, *options);
    MarkMissingFrames(missing, &output.frames);
    WriteStabilizeOutput(output, model, *options, *out);
    spdlog::info("stabilize: {} -> {}", output.BriefReport(), *out);
    if (!truth->empty()) {
      std::vector<PoseFrame> poses;
      for (const StabilizedFrame& f : output.frames) poses.push_back({f.frame, f.head_from_helmet});
      spdlog::info("stabilize: {}", ComparePoses(poses, ReadPosesCsv(*truth)).BriefReport());
    }
    return 0;
  };
}

}  // namespace hmc
