// `hmc track --shot SHOT --calibration CAL --actor DIR --out tracks_2d.csv
//   [--reference_frame N] [--overlay DIR] [--diagnostics FILE.json]
//   [--dot_size PX] [--fixes track_fixes.csv] [--proxies DIR] [--config configs/track.yaml]`: the painted dots of a
// stereo helmet-camera shot, detected in the fisheye frames, named from the
// actor's marker layout at the reference frame and tracked over the shot
// (tracking/track_shot.h; method: docs/tracking.md; files: docs/formats.md).
#include <functional>
#include <memory>
#include <string>

#include <spdlog/spdlog.h>

#include "apps/command.h"
#include "core/file_util.h"
#include "core/logging.h"
#include "tracking/track_shot.h"

namespace hmc {

HMC_COMMAND(Track, "", "track",
            "Detect, name and track the painted dots of a stereo helmet-camera shot "
            "(writes tracks_2d.csv)") {
  auto options = std::make_shared<TrackOptions>();
  auto binding = BindOptions(app, options.get());
  auto input = std::make_shared<TrackInput>();
  auto shot = std::make_shared<std::string>();
  auto calibration = std::make_shared<std::string>();
  auto actor = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  auto overlay = std::make_shared<std::string>();
  auto diagnostics = std::make_shared<std::string>();
  auto dot_size = std::make_shared<double>(0);
  auto fixes = std::make_shared<std::string>();
  auto proxies = std::make_shared<std::string>();
  app->add_option("--shot", *shot, "Shot folder (cam0/cam1 videos or image folders)")->required();
  app->add_option("--calibration", *calibration, "calibration.yaml of the rig")->required();
  app->add_option("--actor", *actor, "Actor package (its markers are named)")->required();
  app->add_option("--out", *out, "tracks_2d.csv to write")->required();
  app->add_option("--overlay", *overlay, "Folder for PNG frames with the named dots drawn");
  app->add_option("--diagnostics", *diagnostics, "JSON with per-frame, per-camera counts");
  app->add_option("--fixes", *fixes,
                  "track_fixes.csv (from hmc review) applied as hard constraints; the tracking "
                  "goes on from them (docs/review.md)");
  app->add_option("--proxies", *proxies,
                  "Folder for the footage proxies of hmc review (JPEGs of the face per camera and "
                  "frame, proxies.json)");
  app->add_option("--dot_size", *dot_size,
                  "Expected dot diameter in px (same as --detect.dot_size_px; default: measured)");
  return [=] {
    binding->Apply();
    if (*dot_size > 0) options->detect.dot_size_px = *dot_size;
    RequireValid(*options, "track");
    const std::filesystem::path out_dir = std::filesystem::path(*out).parent_path();
    PrepareOutputPaths({{*out, "--out"},
                        {*diagnostics, "--diagnostics"},
                        {*overlay, "--overlay", true},
                        {*proxies, "--proxies", true},
                        SideFile(out_dir / "options_used.yaml", "track"),
                        SideFile(out_dir / "summary.json", "track"),
                        fixes->empty() ? OutputFlag{}
                                       : SideFile(out_dir / "track_fixes_used.csv", "track",
                                                  "frame,camera,marker,action,x,y,to")},
                       {{*shot, "--shot"},
                        {*calibration, "--calibration"},
                        {*actor, "--actor"},
                        {options->footage.cam0, "cam0"},
                        {options->footage.cam1, "cam1"},
                        {*fixes, "--fixes"}});
    StageTimer timer("track");
    TrackInput in;
    in.shot = *shot;
    in.calibration = *calibration;
    in.actor = *actor;
    in.out = *out;
    in.diagnostics = *diagnostics;
    in.fixes = *fixes;
    TrackOutput output;
    // The overlay frames and the proxies are folders written whole: a
    // re-run over fewer frames leaves none of the earlier run's pictures.
    std::function<void()> run = [&] { output = RunTrack(in, *options); };
    if (!overlay->empty()) {
      run = [&, inner = run] {
        WriteFolderAtomic(*overlay, "hmc track --overlay", [&](const std::filesystem::path& dir) {
          in.overlay_dir = dir;
          inner();
        });
      };
    }
    if (!proxies->empty()) {
      run = [&, inner = run] {
        WriteFolderAtomic(*proxies, "hmc track --proxies", [&](const std::filesystem::path& dir) {
          in.proxy_dir = dir;
          inner();
        });
      };
    }
    run();
    spdlog::info("track: {} -> {}", output.summary.BriefReport(), *out);
    return 0;
  };
}

}  // namespace hmc
