// `hmc triangulate --tracks tracks_2d.csv --calibration CAL --out
//   bundles_helmet.csv [--diagnostics triangulation.csv] [--rays rays.csv]
//   [--truth SHOT] [--config configs/triangulate.yaml]`: every labelled dot
// seen by two cameras becomes a 3D bundle in helmet space
// (triangulation/triangulate.h; method: docs/calibration.md). Writes the
// bundles, rays.csv (markers seen by one camera), options_used.yaml and,
// last, summary.json beside --out (docs/formats.md).
//
// --tracks may also be a synthetic shot's dots_2d.csv (recognised by its
// header): --dots centroid takes cx,cy of the `full` dots (what a perfect
// tracker reports), --dots exact the x,y of every visible dot. --truth SHOT
// compares the bundles with SHOT/bundles_helmet.csv and counts the coverage
// of SHOT/dots_2d.csv.
#include <cmath>
#include <filesystem>
#include <map>
#include <memory>
#include <set>
#include <string>

#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "apps/command.h"
#include "core/calibration.h"
#include "core/file_util.h"
#include "core/frame_gaps.h"
#include "core/logging.h"
#include "core/text.h"
#include "core/tracks_2d.h"
#include "core/actor.h"
#include "core/actor_cache.h"
#include "core/day_markers.h"
#include "triangulation/dot_offset.h"
#include "triangulation/triangulate.h"

namespace hmc {
namespace {

bool IsDotsFile(const std::filesystem::path& path) {
  const std::string text = ReadFile(path);
  bool dots = false, first = true;
  ForEachLine(text, [&](int, std::string_view line) {
    if (!first || Trim(line).empty()) return;
    first = false;
    dots = Trim(line).substr(0, 24) == "frame,camera,marker,x,y,";
    dots = dots && line.find("disc") != std::string_view::npos;
  });
  return dots;
}

nlohmann::json AccuracyJson(const TriangulationAccuracy& a) {
  return {{"compared", a.compared},     {"median_mm", a.median_mm},
          {"rms_mm", a.rms_mm},         {"p99_mm", a.p99_mm},
          {"max_mm", a.max_mm},         {"seen_in_every_camera", a.seen_both},
          {"seen_and_triangulated", a.seen_both_triangulated},
          {"coverage", a.coverage()},
          {"full_in_every_camera", a.full_both},
          {"full_and_triangulated", a.full_both_triangulated},
          {"full_coverage", a.full_coverage()}};
}

// The frames between the first and last frame of the tracks that gave no
// bundle, with why (docs/reliability.md, promise 2): a frame lost in one
// camera (a corrupt video frame) or in all of them. Missing runs longer
// than kMaxMissingFrames are listed as one entry (the later stages refuse
// them as stray frame numbers).
nlohmann::json FlaggedFrames(const std::vector<Track2d>& tracks,
                             const std::vector<BundleFrame>& bundles, const HelmetRig& rig) {
  std::map<int, std::map<std::string, int>> named;  // frame -> camera -> named dots
  for (const Track2d& t : tracks) ++named[t.frame][t.camera];
  std::set<int> with_bundles;
  for (const BundleFrame& b : bundles) {
    if (!b.bundles.empty()) with_bundles.insert(b.frame);
  }
  nlohmann::json flagged = nlohmann::json::array();
  int previous = named.empty() ? 0 : named.begin()->first - 1;
  for (const auto& [frame, per_camera] : named) {
    if (frame - previous - 1 > kMaxMissingFrames) {
      flagged.push_back({{"frame", previous + 1},
                         {"last_frame", frame - 1},
                         {"reason", "no tracks in any camera"}});
    } else {
      for (int n = previous + 1; n < frame; ++n) {
        flagged.push_back({{"frame", n}, {"reason", "no tracks in any camera"}});
      }
    }
    previous = frame;
    if (with_bundles.count(frame)) continue;
    std::string counts;
    for (const HelmetCamera& c : rig.cameras) {
      const auto it = per_camera.find(c.name);
      counts += fmt::format("{}{} {}", counts.empty() ? "" : ", ", c.name,
                            it == per_camera.end() ? 0 : it->second);
    }
    flagged.push_back(
        {{"frame", frame},
         {"reason", fmt::format("no marker seen by two cameras (named dots: {})", counts)}});
  }
  return flagged;
}

}  // namespace

HMC_COMMAND(Triangulate, "", "triangulate",
            "Triangulate the labelled 2D dots of both cameras into 3D bundles (helmet space)") {
  auto options = std::make_shared<TriangulateOptions>();
  auto binding = BindOptions(app, options.get());
  auto tracks_path = std::make_shared<std::string>();
  auto calibration = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  auto diagnostics = std::make_shared<std::string>();
  auto rays = std::make_shared<std::string>();
  auto truth = std::make_shared<std::string>();
  auto dots = std::make_shared<std::string>("centroid");
  auto actor_dir = std::make_shared<std::string>();
  app->add_option("--tracks", *tracks_path,
                  "tracks_2d.csv (or a synthetic shot's dots_2d.csv, see --dots)")
      ->required();
  app->add_option("--calibration", *calibration, "calibration.yaml of the rig")->required();
  app->add_option("--out", *out, "bundles_helmet.csv to write (helmet space, mm)")->required();
  app->add_option("--diagnostics", *diagnostics,
                  "triangulation.csv to write: per marker-frame status, views, residual per "
                  "camera (px), ray angle (deg), depth uncertainty (mm)");
  app->add_option("--rays", *rays,
                  "rays.csv to write for markers seen by one camera (default: beside --out)");
  app->add_option("--truth", *truth,
                  "synthetic shot folder: compare with its bundles_helmet.csv and dots_2d.csv");
  app->add_option("--dots", *dots,
                  "with a dots_2d.csv as --tracks: centroid (cx,cy of full dots) | exact (x,y)")
      ->check(CLI::IsMember({"centroid", "exact"}));
  app->add_option("--actor", *actor_dir,
                  "Actor package: correct each bundle for its painted dot's rim depth, from the "
                  "neutral's curvature at the marker (dot_radius; docs/calibration.md)");
  return [=] {
    binding->Apply();
    RequireValid(*options, "triangulate");
    StageTimer timer("triangulate");
    const std::filesystem::path out_path(*out);
    const std::filesystem::path out_dir =
        out_path.has_parent_path() ? out_path.parent_path() : std::filesystem::path(".");
    const std::filesystem::path rays_path =
        rays->empty() ? out_dir / "rays.csv" : std::filesystem::path(*rays);
    PrepareOutputPaths({{out_path, "--out"},
                        {*diagnostics, "--diagnostics"},
                        rays->empty() ? SideFile(rays_path, "triangulate", kRaysCsvHeader)
                                      : OutputFlag{rays_path, "--rays"},
                        SideFile(out_dir / "options_used.yaml", "triangulate"),
                        SideFile(out_dir / "summary.json", "triangulate")},
                       {{*tracks_path, "--tracks"},
                        {*calibration, "--calibration"},
                        {*truth, "--truth"},
                        {*actor_dir, "--actor"}});
    const HelmetRig rig = ReadCalibration(*calibration);
    const bool from_dots = IsDotsFile(*tracks_path);
    const std::vector<Track2d> tracks =
        from_dots ? TracksFromDots(ReadDots2dCsv(*tracks_path), *dots == "centroid")
                  : ReadTracks2dCsv(*tracks_path);
    std::map<std::string, Vec3> offsets;
    if (!actor_dir->empty()) {
      offsets = DotRimOffsets(*LoadActorForDay(*actor_dir, options->day.markers), options->dot_radius,
                              options->dot_fit_radius);
    }
    const TriangulateOutput result = RunTriangulate(
        {&rig, &tracks, *tracks_path, actor_dir->empty() ? nullptr : &offsets}, *options);
    WriteBundlesCsv(out_path, result.bundles);
    WriteRaysCsv(rays_path, result.rays);
    if (!diagnostics->empty()) WriteTriangulationCsv(*diagnostics, rig, result.records);
    WriteOptionsUsed(binding->fields(), out_dir / "options_used.yaml", "triangulate");

    const TriangulateSummary& s = result.summary;
    nlohmann::json gated = nlohmann::json::array();
    for (const TriangulationRecord& r : result.records) {
      if (r.status != TriangulationStatus::kGated) continue;
      nlohmann::json residuals;
      for (size_t c = 0; c < rig.cameras.size(); ++c) {
        if (!std::isnan(r.residual_px[c])) residuals[rig.cameras[c].name] = r.residual_px[c];
      }
      gated.push_back({{"frame", r.frame}, {"marker", r.marker}, {"residual_px", residuals}});
    }
    nlohmann::json summary = {
        {"stage", "triangulate"},
        {"tracks", *tracks_path},
        {"input", from_dots ? "dots_2d " + *dots : "tracks_2d"},
        {"dot_offset_correction", !actor_dir->empty()},
        {"calibration", *calibration},
        {"frames", s.frames},
        {"candidates", s.candidates},
        {"triangulated", s.triangulated},
        {"gated", s.gated},
        {"inconsistent", s.inconsistent},
        {"pixel_noise_px", s.pixel_noise_px},
        {"parallel", s.parallel},
        {"behind", s.behind},
        {"no_ray", s.no_ray},
        {"mono_rays", s.mono},
        {"rms_residual_px", s.rms_residual_px},
        {"max_residual_px", s.max_residual_px},
        {"median_depth_sigma_mm", s.median_depth_sigma_mm},
        {"seconds", s.seconds},
        {"gated_list", gated},
        {"flagged_frames", FlaggedFrames(tracks, result.bundles, rig)}};
    const nlohmann::json& flagged = summary["flagged_frames"];
    for (size_t i = 0; i < flagged.size() && i < 10; ++i) {
      spdlog::warn("triangulate: frame {} flagged: {}", flagged[i]["frame"].get<int>(),
                   flagged[i]["reason"].get<std::string>());
    }
    if (flagged.size() > 10) {
      spdlog::warn("triangulate: {} frames flagged in all (summary.json)", flagged.size());
    }
    spdlog::info("triangulate: {}", s.BriefReport());
    if (!truth->empty()) {
      const std::filesystem::path shot(*truth);
      const TriangulationAccuracy a = EvaluateTriangulation(
          result.bundles, ReadBundlesCsv(shot / "bundles_helmet.csv"),
          ReadDots2dCsv(shot / "dots_2d.csv"), static_cast<int>(rig.cameras.size()));
      summary["truth"] = AccuracyJson(a);
      spdlog::info("triangulate: {}", a.BriefReport());
    }
    WriteFileAtomic(out_dir / "summary.json", summary.dump(1) + "\n");
    return 0;
  };
}

}  // namespace hmc
