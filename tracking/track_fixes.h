// Track fixes (docs/formats.md, "track_fixes.csv"; docs/review.md): what a
// TD corrected on the review page, applied by `hmc track --fixes` (and
// `hmc run --from track --fixes`) as hard constraints at their frames; the
// tracker goes on from the fixed state, so one fix corrects the frames
// after it too (tracking/marker_tracker.h, MarkerTracker::ApplyFixes).
//
//   frame,camera,marker,action,x,y,to
//   rename  the dot of `marker` (or, with x,y, the detection nearest
//           (x, y)) is marker `to`; `marker` may be empty (an unnamed dot);
//           the confusion is kept fixed on the later frames
//           (MarkerTracker::ResolveConfusions)
//   unname  the dot of `marker` (or nearest (x, y)) has no name from this
//           frame on: the tracker follows it and names it no more until a
//           later fix names it (rename or move to it) or it is not found
//   absent  `marker` is not in this camera's view from this frame on,
//           until a later fix names it (rename ... to it, or move it)
//   move    `marker` is at (x, y): the detection there, else that point
#pragma once

#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "core/types.h"

namespace hmc {

enum class TrackFixAction { kRename, kUnname, kAbsent, kMove };

struct TrackFix {
  int frame = 0;
  std::string camera;
  std::string marker;  // may be empty for rename
  TrackFixAction action = TrackFixAction::kRename;
  bool has_pixel = false;
  Vec2 pixel = Vec2::Zero();  // px in the fisheye image (OpenCV pixel centres)
  std::string to;             // rename only
  int line = 0;               // in the file, for messages
};

const char* TrackFixActionName(TrackFixAction action);

// Reads and checks track_fixes.csv: the header, the action, a frame >= 1,
// the fields each action needs (rename: `to`; unname: `marker` or x,y;
// absent: `marker`; move: `marker`, x and y), and -- given -- that
// cameras and markers are known ones. Throws InputError naming the file,
// the line and what is wrong. Fixes come sorted by frame, file order
// within a frame.
std::vector<TrackFix> ReadTrackFixesCsv(const std::filesystem::path& path,
                                        const std::vector<std::string>& cameras = {},
                                        const std::vector<std::string>& markers = {});

// The fixes' CSV text (the header, then one row per fix).
std::string TrackFixesCsvText(const std::vector<TrackFix>& fixes);

}  // namespace hmc
