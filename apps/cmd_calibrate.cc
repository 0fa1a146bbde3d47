// `hmc calibrate --shot SHOT --calibration NOMINAL.yaml --out CAL.yaml
//   [--report FILE.json] [--frames A:B] [--sample N]
//   [--refine extrinsics|intrinsics] [--import_kalibr camchain.yaml]
//   [--export_kalibr FILE] [--config configs/calibrate.yaml]`: the rig's
// calibration for this shot from the AprilTags on the helmet
// (triangulation/rig_calibration.h; method: docs/calibration.md). Writes
// CAL.yaml (same format as the nominal, atomically), options_used.yaml
// and, last, summary.json (the report) beside it, the report (FILE.json) and, with --export_kalibr, a Kalibr
// camchain. Refuses (exit 2, nothing but the report written) when a camera
// moved during the shot (choose one side with --frames), and when a camera
// is solved beyond max_move_mm / max_turn_deg of its nominal pose (names
// swapped, footage duplicated, another rig's calibration).
#include <filesystem>
#include <memory>
#include <string>

#include <spdlog/spdlog.h>

#include "apps/command.h"
#include "core/calibration.h"
#include "core/file_util.h"
#include "core/kalibr.h"
#include "core/logging.h"
#include "triangulation/rig_calibration.h"

namespace hmc {

HMC_COMMAND(Calibrate, "", "calibrate",
            "Calibrate the helmet rig for a shot from the AprilTags on the helmet") {
  auto options = std::make_shared<CalibrateOptions>();
  auto binding = BindOptions(app, options.get());
  auto shot = std::make_shared<std::string>();
  auto nominal = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  auto report = std::make_shared<std::string>();
  auto import_kalibr = std::make_shared<std::string>();
  auto export_kalibr = std::make_shared<std::string>();
  app->add_option("--shot", *shot, "Shot folder with cam0/cam1 footage")->required();
  app->add_option("--calibration", *nominal,
                  "Nominal calibration.yaml (start of the solve; tag family, sizes and layout)")
      ->required();
  app->add_option("--out", *out, "Calibrated calibration.yaml to write")->required();
  app->add_option("--report", *report, "Report to write (JSON; docs/formats.md)");
  app->add_option("--import_kalibr", *import_kalibr,
                  "Kalibr camchain.yaml: its intrinsics (and T_cn_cnm1) replace the nominal's "
                  "before the solve");
  auto truth = std::make_shared<std::string>();
  app->add_option("--truth", *truth,
                  "A true calibration.yaml (synthetic shots: calibration_true.yaml) to compare "
                  "the result with, in the log and the report");
  app->add_option("--export_kalibr", *export_kalibr, "Also write the result as a Kalibr camchain");
  return [=] {
    binding->Apply();
    RequireValid(*options, "calibrate");
    StageTimer timer("calibrate");
    const std::filesystem::path out_path(*out);
    const std::filesystem::path out_dir =
        out_path.has_parent_path() ? out_path.parent_path() : std::filesystem::path(".");
    PrepareOutputPaths({{out_path, "--out"},
                        {*report, "--report"},
                        {*export_kalibr, "--export_kalibr"},
                        SideFile(out_dir / "options_used.yaml", "calibrate"),
                        SideFile(out_dir / "summary.json", "calibrate")},
                       {{*shot, "--shot"},
                        {*nominal, "--calibration"},
                        {*import_kalibr, "--import_kalibr"},
                        {*truth, "--truth"}});
    HelmetRig rig = ReadCalibration(*nominal);
    if (!import_kalibr->empty()) {
      rig = ApplyKalibr(rig, ReadKalibrCamchain(*import_kalibr), *import_kalibr);
      spdlog::info("calibrate: intrinsics from {}", *import_kalibr);
    }
    CalibrateOutput result = RunCalibrate(*shot, *nominal, rig, *options);
    if (!truth->empty() && !result.summary.change.found) {
      result.has_truth = true;
      result.truth = CompareRigs(result.rig, ReadCalibration(*truth));
      spdlog::info("calibrate: against {}: {}", *truth, result.truth.BriefReport());
    }
    if (!report->empty()) WriteFileAtomic(*report, CalibrationReportJson(result));
    const CalibrateSummary& s = result.summary;
    if (s.change.found) {
      spdlog::error(
          "calibrate: camera {} moved at frame {} (its tag corners shift by {:.2f} px RMS "
          "between frames {} and {}); refusing to average over the change: calibrate each "
          "side with --frames :{} or --frames {}:",
          s.change.camera, s.change.frame, s.change.shift_px, s.change.last_before,
          s.change.frame, s.change.frame - 1, s.change.frame);
      return 2;
    }
    // A nominal rig is off by millimetres; a camera solved centimetres or
    // degrees away sees another camera's view of the tags (issue 45).
    for (const CameraCalibrationReport& c : result.cameras) {
      if (c.moved_mm > options->max_move_mm || c.turned_deg > options->max_turn_deg) {
        spdlog::error(
            "calibrate: {} would move {:.1f} mm and turn {:.1f} deg from its pose in {} (beyond "
            "max_move_mm {} / max_turn_deg {} of a nominal rig): its footage does not look like "
            "that camera's view. Likely: the cameras' names swapped in {}, two cameras with the "
            "same footage (one video a copy of the other), or the calibration of another rig. "
            "Refusing to write {}",
            c.name, c.moved_mm, c.turned_deg, *nominal, options->max_move_mm,
            options->max_turn_deg, *nominal, *out);
        return 2;
      }
    }
    for (const CameraCalibrationReport& c : result.cameras) {
      spdlog::info(
          "calibrate: {}: {} tag sightings, RMS {:.3f} px, max {:.3f} px; moved {:.3f} mm, "
          "{:.4f} deg; focal {:+.2f} px, principal point {:.2f} px",
          c.name, c.detections, c.rms_px, c.max_px, c.moved_mm, c.turned_deg, c.focal_change_px,
          c.principal_change_px);
    }
    for (const TagCalibrationReport& t : result.tags) {
      std::string seen;
      for (size_t c = 0; c < t.detections.size(); ++c) {
        seen += fmt::format("{}{} {}", c ? ", " : "", result.rig.cameras[c].name, t.detections[c]);
      }
      spdlog::info("calibrate: tag {}: seen {}; RMS {:.3f} px, max {:.3f} px; moved {:.3f} mm, "
                   "{:.4f} deg",
                   t.id, seen, t.rms_px, t.max_px, t.moved_mm, t.turned_deg);
    }
    WriteCalibration(out_path, result.rig);
    if (!export_kalibr->empty()) WriteKalibrCamchain(*export_kalibr, result.rig);
    WriteOptionsUsed(binding->fields(), out_dir / "options_used.yaml", "calibrate");
    WriteFileAtomic(out_dir / "summary.json", CalibrationReportJson(result));  // last
    spdlog::info("calibrate: {} -> {}", s.BriefReport(), *out);
    return 0;
  };
}

}  // namespace hmc
