// The run report (`hmc report`, the last stage of `hmc run`): one
// self-contained HTML page a TD opens after a run -- per stage its summary;
// plots over frames (named dots per camera, triangulated bundles and their
// residuals, head motion and stabilization residual, jaw curves, the solve's
// bundles outside their data and residuals); a contact sheet of footage
// frames with the named dots beside the reconstructed mesh; warnings with
// their frames. When the shot folder holds ground truth (a synthetic shot:
// docs/formats.md, "Shot ground truth"), the error against it per stage (px,
// mm, degrees) and an error heat map of the mesh. Pictures are PNGs
// rendered by hmc, embedded in the page (no network needed) and also
// written beside it. docs/pipeline.md, "The report".
#pragma once

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "core/options.h"
#include "core/tracks_2d.h"

namespace hmc {

struct ReportOptions {
  int contact_frames = 4;       // footage frames on the contact sheet (0 = none)
  double contact_scale = 0.35;  // footage image scale on the contact sheet
  int mesh_px = 320;            // height of the mesh renders (px)
  double error_max_mm = 0.5;    // top of the error colour scale (mm)

  void Register(OptionFields* fields);
  bool Check() const;
};

struct ReportInput {
  std::string work;   // the run's workspace
  std::string shot;   // the shot folder (footage; ground truth if present)
  std::string actor;  // the actor package
  std::string out;    // folder to write report.html and its pictures into
};

// One warning of a stage, with the markers and frames it names (both may
// be empty), so that the report lists them and the review jumps to them.
struct ReportWarning {
  std::string stage;
  std::string text;
  std::vector<std::string> markers;
  std::vector<int> frames;  // sorted
  std::string Line() const;  // "stage: text"
  nlohmann::json ToJson() const;
};

struct ReportSummary {
  int stages_present = 0;
  bool has_truth = false;
  std::vector<ReportWarning> warnings;
  nlohmann::json accuracy;  // per stage, against the ground truth when present
  // Every plot of the page: [{title, x_label, y_label, y_from_zero,
  // series: [{name, points: [[x, y], ...]}]}] (what plots.json holds).
  nlohmann::json plots = nlohmann::json::array();
  std::string BriefReport() const;
};

// Reads what the workspace holds (a stage that did not run is shown as
// missing), writes OUT/report.html, OUT/plots.json (the plots' data and
// the warnings, which `hmc review` shows), OUT/contact_sheet.png and, with
// ground truth, OUT/mesh_error.png and OUT/accuracy.json. Throws
// InputError for unreadable files, naming them.
ReportSummary WriteRunReport(const ReportInput& input, const ReportOptions& options);

// Calls `body` with each frame record ({frame, ok, bundles, ...}) of a
// solve's diagnostics.json (docs/formats.md) as the streaming parser
// completes it, then drops it: a long shot's file is never held parsed.
// Throws InputError naming the file when it is not JSON.
void ForEachSolveFrame(const std::filesystem::path& diagnostics,
                       const std::function<void(const nlohmann::json&)>& body);

// The box around `camera`'s named dots over the whole shot, with a margin,
// inside an image of `size` (the whole image without tracks): how the
// contact sheet and the review's proxies frame the face.
cv::Rect NamedDotsBox(const std::vector<Track2d>& tracks, const std::string& camera, cv::Size size);

}  // namespace hmc
