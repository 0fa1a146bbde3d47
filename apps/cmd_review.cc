// `hmc review --work WORK [--out WORK/review] [--shot SHOT]`: a static page
// to scrub a run's take, see the solved mesh in 3D and fix the tracks
// (pipeline/review.h, docs/review.md). Open OUT/index.html in a browser;
// its fixes export as track_fixes.csv for `hmc run --from track --fixes`.
#include <memory>
#include <string>

#include <spdlog/spdlog.h>

#include "apps/command.h"
#include "core/logging.h"
#include "pipeline/review.h"

namespace hmc {

HMC_COMMAND(Review, "", "review",
            "Write the review page of a run (WORK/review/index.html): footage with the tracked "
            "dots, the mesh in 3D, plots, warnings, and track fixes to export") {
  auto options = std::make_shared<ReviewOptions>();
  auto work = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  auto shot = std::make_shared<std::string>();
  app->add_option("--work", *work, "Workspace of `hmc run`")->required();
  app->add_option("--out", *out, "Folder to write the page into (default: WORK/review)");
  app->add_option("--shot", *shot,
                  "Shot folder (footage, ground truth; default: the one the run recorded)");
  auto binding = BindOptions(app, options.get());
  return [=] {
    binding->Apply();
    RequireValid(*options, "review");
    ReviewInput input;
    input.work = *work;
    input.out = out->empty() ? std::filesystem::path(*work) / "review" : std::filesystem::path(*out);
    input.shot = *shot;
    // --work is read, not written: the page goes into its own folder
    // (WORK/review beside the stage folders, which hmc run leaves alone).
    PrepareOutputPaths({{input.out.string(), "--out", true}}, {{*shot, "--shot"}});
    StageTimer timer("review");
    const ReviewSummary summary = WriteReview(input, *options);
    spdlog::info("review: {} -> {}", summary.BriefReport(), (input.out / "index.html").string());
    return 0;
  };
}

}  // namespace hmc
