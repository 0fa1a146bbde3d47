// `hmc track`: footage in, labelled marker tracks out (docs/tracking.md).
// Reads the shot's two fisheye videos (tracking/footage_reader.h), detects
// the painted dots in every original frame (tracking/dot_detector.h), names
// them at the reference frame from the actor's neutral marker layout and
// tracks them over the shot (tracking/marker_tracker.h). Writes
// tracks_2d.csv (core/tracks_2d.h), options_used.yaml and, last,
// summary.json beside it, and optionally a diagnostics JSON and overlay
// PNGs (docs/formats.md).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "core/day_markers.h"
#include "core/options.h"
#include "core/tracks_2d.h"
#include "tracking/dot_detector.h"
#include "tracking/footage_reader.h"
#include "tracking/marker_tracker.h"

namespace hmc {

struct TrackOptions {
  FootageOptions footage;        // cam0, cam1, frames, offset1 (top level)
  int reference_frame = 1;       // frame where the actor is near neutral and names are given
  int threads = 0;               // worker threads (0 = all cores)
  DotDetectorOptions detect;     // detect.*
  MarkerTrackerOptions tracker;  // track.*
  DayMarkersOptions day;         // markers: the day's markers (core/day_markers.h)

  void Register(OptionFields* fields);
  bool Check() const;
};

struct TrackInput {
  std::filesystem::path shot;         // shot folder (videos or image folders)
  std::filesystem::path calibration;  // calibration.yaml
  std::filesystem::path actor;        // actor package (markers)
  std::filesystem::path out;          // tracks_2d.csv to write
  std::filesystem::path overlay_dir;  // PNGs with the named dots ("" = none)
  std::filesystem::path diagnostics;  // JSON per frame and camera ("" = none)
  // track_fixes.csv to apply as hard constraints ("" = none;
  // tracking/track_fixes.h); the fixes used are written beside `out` as
  // track_fixes_used.csv.
  std::filesystem::path fixes;
  // Footage proxies for `hmc review` ("" = none): per camera and tracked
  // frame a JPEG of the face (the box of the reference frame's named dots
  // with a wide margin), `proxy_height` rows, written as the frame is
  // decoded for the tracking anyway; and proxies.json (docs/formats.md).
  std::filesystem::path proxy_dir;
  int proxy_height = 360;   // px
  int proxy_quality = 80;   // JPEG quality (1-100)
};

struct TrackSummary {
  int frames = 0;             // frames read (from the reference frame on)
  int skipped_views = 0;      // camera images that failed to decode
  int reference_frame = 0;    // the frame labelled
  std::vector<double> dot_size_px;  // per camera, used by the detector
  // Per camera: the encoding its values were read as ("srgb", "linear")
  // and why (FootageReader::transfer_why).
  std::vector<std::string> transfer, transfer_why;
  ReferenceLabelling labelling;
  double mean_detections = 0;  // per view
  double mean_named = 0;       // per view
  int reacquired = 0;
  int swaps_caught = 0;
  // Views whose exposure was scaled back to the reference frame's (their
  // mean level more than 3 % off it).
  int exposure_matched_views = 0;
  int64_t rows = 0;
  double seconds = 0;
  // The actor's markers named in no view of the shot: hidden all along,
  // at a grazing angle, left unnamed, not painted, or painted elsewhere.
  std::vector<std::string> never_found;
  // Those of them whose dot was missing where it should have been seen
  // (CameraFrameTracks::vacant) in at least half the frames: not painted,
  // or painted elsewhere, and then the dots near them may carry wrong
  // names; warned.
  std::vector<std::string> missing_dots;
  // Dots lost mid-take (MarkerTracker::lost_since; docs/tracking.md, "Dots
  // lost mid-take"): the marker, the first frame it was missing, and the
  // frame it was named in both cameras again (0: lost to the end of the
  // take, warned). A lost marker has no rows from `from_frame` until then.
  struct LostDot {
    std::string marker;
    int from_frame = 0;
    int back_frame = 0;
  };
  std::vector<LostDot> lost_dots;
  // Track fixes (TrackInput::fixes): rows read, applied, and the lines
  // of the file whose dot was not found (or whose frame was not tracked).
  int fixes = 0;
  int fixes_applied = 0;
  std::vector<int> fixes_unmatched_lines;
  std::vector<std::string> warnings;
  std::string BriefReport() const;
};

struct TrackOutput {
  std::vector<Track2d> tracks;
  TrackSummary summary;
};

// Throws InputError naming the file on a missing or unreadable input (a
// video of the wrong size for the calibration, an unreadable file), or when
// the reference frame cannot be labelled. Frames that fail to decode are
// skipped and reported (diagnostics, warnings).
TrackOutput RunTrack(const TrackInput& input, const TrackOptions& options);

}  // namespace hmc
