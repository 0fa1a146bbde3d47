// `hmc report --work WORK --shot SHOT --actor DIR --out DIR`: the run report
// page (pipeline/report.h): what every stage of the workspace did, plots
// over frames, a contact sheet, warnings, and the error against the shot's
// ground truth when it has one, and summary.json (the warnings). The last
// stage of `hmc run`.
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "apps/command.h"
#include "core/file_util.h"
#include "core/logging.h"
#include "pipeline/report.h"

namespace hmc {

HMC_COMMAND(Report, "", "report",
            "Write the run report (report.html): stage summaries, plots, contact sheet, "
            "warnings, error against ground truth when present") {
  auto input = std::make_shared<ReportInput>();
  auto options = std::make_shared<ReportOptions>();
  app->add_option("--work", input->work, "Workspace of `hmc run`")->required();
  app->add_option("--shot", input->shot, "Shot folder (footage; ground truth if present)")->required();
  app->add_option("--actor", input->actor, "Actor package folder")->required();
  app->add_option("--out", input->out, "Folder to write report.html and its pictures into")->required();
  auto binding = BindOptions(app, options.get());
  return [=] {
    binding->Apply();
    RequireValid(*options, "report");
    // --work is not an input folder here: hmc run writes its report
    // stage into the workspace by design (pipeline/workspace.h).
    PrepareOutputPaths({{input->out, "--out", true}},
                       {{input->shot, "--shot"}, {input->actor, "--actor"}});
    StageTimer timer("report");
    // Written whole: a re-run without ground truth leaves no accuracy.json
    // or error picture of an earlier one (docs/reliability.md).
    ReportSummary summary;
    WriteFolderAtomic(input->out, "hmc report", [&](const std::filesystem::path& dir) {
      ReportInput in = *input;
      in.out = dir.string();
      summary = WriteRunReport(in, *options);
      WriteOptionsUsed(binding->fields(), dir / "options_used.yaml", "report");
      // What a shoot day's report lists per take (pipeline/batch.h); in a
      // workspace it becomes the stage's command_summary.
      // The warnings as lines (the day report lists them; plots.json has
      // their markers and frames).
      std::vector<std::string> warnings;
      for (const ReportWarning& w : summary.warnings) warnings.push_back(w.Line());
      const nlohmann::json brief = {{"stage", "report"},
                                    {"stages_present", summary.stages_present},
                                    {"has_truth", summary.has_truth},
                                    {"warnings", warnings}};
      WriteFileAtomic(dir / "summary.json", brief.dump(1) + "\n");
    });
    spdlog::info("report: {} -> {}/report.html", summary.BriefReport(), input->out);
    return 0;
  };
}

}  // namespace hmc
