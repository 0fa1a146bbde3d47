// `hmc undistort --shot SHOT --calibration CAL --out DIR [--camera cam0|cam1|both]
//   [--fov_deg F] [--tracks tracks_2d.csv] [--video]`: the fisheye frames
// remapped exactly (the camera's lens model, core/camera.h) to pinhole views,
// as PNG frames or an FFV1 video per camera; with --tracks the named dots
// are drawn (tracking/undistort.h; files: docs/formats.md).
#include <memory>
#include <string>

#include <spdlog/spdlog.h>

#include "apps/command.h"
#include "core/file_util.h"
#include "core/logging.h"
#include "tracking/undistort.h"

namespace hmc {

HMC_COMMAND(Undistort, "", "undistort",
            "Remap the fisheye frames of a shot to pinhole views (PNG frames or FFV1)") {
  auto options = std::make_shared<UndistortOptions>();
  auto binding = BindOptions(app, options.get());
  auto shot = std::make_shared<std::string>();
  auto calibration = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  auto tracks = std::make_shared<std::string>();
  app->add_option("--shot", *shot, "Shot folder (cam0/cam1 videos or image folders)")->required();
  app->add_option("--calibration", *calibration, "calibration.yaml of the rig")->required();
  app->add_option("--out", *out, "Folder to write")->required();
  app->add_option("--tracks", *tracks, "tracks_2d.csv whose named dots are drawn");
  return [=] {
    binding->Apply();
    RequireValid(*options, "undistort");
    PrepareOutputPaths({{*out, "--out", true}},
                       {{*shot, "--shot"}, {*calibration, "--calibration"}, {*tracks, "--tracks"}});
    StageTimer timer("undistort");
    // Written whole: a re-run with other frames or cameras leaves nothing
    // of the earlier one (docs/reliability.md).
    UndistortSummary summary;
    WriteFolderAtomic(*out, "hmc undistort", [&](const std::filesystem::path& dir) {
      summary = RunUndistort({*shot, *calibration, dir, *tracks}, *options);
    });
    spdlog::info("undistort: {} -> {}", summary.BriefReport(), *out);
    return 0;
  };
}

}  // namespace hmc
