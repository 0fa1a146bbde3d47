// `hmc register --shot SHOT --actor DIR --calibration CAL --out DAY_MARKERS
//   [--frames A:B] [--report FILE.json] [--picture FILE.png]
//   [--config FILE]`: the day's markers from a neutral take: where each
// painted dot sits on the actor's neutral (registration/register.h; method
// and measured accuracy: docs/registration.md; files: docs/formats.md).
// Writes DAY_MARKERS in markers.csv's format, the report (JSON) and a
// picture of the offsets beside it (register_report.json,
// register_offsets.png by default).
#include <memory>
#include <string>

#include <spdlog/spdlog.h>

#include "apps/command.h"
#include "core/actor_cache.h"
#include "core/day_markers.h"
#include "core/file_util.h"
#include "core/logging.h"
#include "core/temp_dir.h"
#include "registration/register.h"

namespace hmc {

HMC_COMMAND(Register, "", "register",
            "Register the day's painted dots on the actor from a neutral take (writes the "
            "day's markers.csv)") {
  auto options = std::make_shared<RegisterOptions>();
  auto binding = BindOptions(app, options.get());
  auto shot = std::make_shared<std::string>();
  auto actor = std::make_shared<std::string>();
  auto calibration = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  auto report = std::make_shared<std::string>();
  auto picture = std::make_shared<std::string>();
  app->add_option("--shot", *shot, "Shot folder of a neutral take (cam0/cam1)")->required();
  app->add_option("--actor", *actor, "Actor package (its markers are where the dots should be)")
      ->required();
  app->add_option("--calibration", *calibration, "calibration.yaml of the rig")->required();
  app->add_option("--out", *out, "The day's markers to write (markers.csv format)")->required();
  app->add_option("--report", *report,
                  "Report to write (JSON; default: register_report.json beside --out)");
  app->add_option("--picture", *picture,
                  "Picture of the offsets to write (PNG; default: register_offsets.png beside "
                  "--out)");
  return [=] {
    binding->Apply();
    RequireValid(*options, "register");
    const std::filesystem::path out_path(*out);
    const std::filesystem::path out_dir =
        out_path.has_parent_path() ? out_path.parent_path() : std::filesystem::path(".");
    const std::filesystem::path report_path =
        report->empty() ? out_dir / "register_report.json" : std::filesystem::path(*report);
    const std::filesystem::path picture_path =
        picture->empty() ? out_dir / "register_offsets.png" : std::filesystem::path(*picture);
    PrepareOutputPaths({{out_path, "--out"},
                        {report_path, "--report"},
                        {picture_path, "--picture"}},
                       {{*shot, "--shot"}, {*calibration, "--calibration"}, {*actor, "--actor"}});
    StageTimer timer("register");
    TempDir work("hmc_register");
    const RegisterOutput output =
        RunRegister({*shot, *calibration, *actor, work.path()}, *options);
    const std::shared_ptr<const Actor> package = LoadActorShared(*actor);
    const ObjPolygons polygons = NeutralPolygons(*package);
    WriteFileAtomic(out_path,
                    FormatMarkersCsv(output.markers, &polygons,
                                     "# the day's markers (hmc register --shot " + *shot + ")\n"));
    WriteFileAtomic(report_path, RegisterReportJson(output));
    WriteOffsetPicture(*package, output, picture_path);
    spdlog::info("register: {} -> {}", output.BriefReport(), *out);
    return 0;
  };
}

}  // namespace hmc
