// Scores tracks_2d.csv against a synthetic shot's dots_2d.csv (the issue's
// targets; docs/tracking.md, "Measured accuracy"). Truth is read
// independently of the tracker: per (frame, camera, marker) the exact
// projection x, y, the disc state and, for `full` dots, the intensity
// centroid cx, cy.
//
//  - accuracy: |track - (cx, cy)| over the named `full` dot-views;
//  - recall: named / present for `full` and `partial` dot-views;
//  - hidden rows: rows on `hidden` dot-views / hidden dot-views;
//  - wrong names: rows more than `wrong_px` from their own marker's dot, or
//    nearer another marker's (visible) dot than their own, or for a marker
//    the truth does not place in the image; split into those nearer another
//    marker's dot (`wrong_other`: a name on the wrong dot) and the rest
//    (`wrong_off`: more than `wrong_px` from its own, nearest to no other:
//    on a partial dot mostly the centroid of the part that is seen);
//  - partial dot-views by how much of the disc is seen (`seen` in
//    dots_2d.csv, when present): recall of those with at least half of it.
//  - whole dot-views (`whole` 1 in dots_2d.csv, when present: the whole
//    disc in view however grazing, so full dots and the partial ones that
//    are only foreshortened) by the view cosine at the marker's point, in
//    kCosBins: recall, and the centre error against the rim centroid
//    (wcx, wcy). The wrong-name test measures a whole dot's row from that
//    centroid too.
// Only frames from the first tracked frame on are counted.
#pragma once

#include <map>
#include <string>
#include <vector>

#include "core/tracks_2d.h"

namespace hmc {

// Lower edges of the view-cosine bins of whole dots: [0, 0.15), [0.15,
// 0.3), [0.3, 0.4), [0.4, 1] (issue 44: dots seen edge-on).
constexpr double kCosBins[] = {0, 0.15, 0.3, 0.4};
constexpr int kNumCosBins = 4;
std::string CosBinName(int bin);  // "0-0.15", ..., ">=0.4"

struct WholeDotBin {
  int64_t views = 0, named = 0;
  double median_px = 0, p95_px = 0;  // named views vs (wcx, wcy)
  double Recall() const { return views ? static_cast<double>(named) / views : 0; }
};

struct TrackScore {
  int64_t rows = 0;
  int64_t full = 0, full_named = 0;
  int64_t partial = 0, partial_named = 0;
  int64_t hidden = 0, hidden_rows = 0;
  int64_t partial_half = 0, partial_half_named = 0;  // partial, seen >= 0.5
  int64_t wrong = 0, wrong_other = 0, wrong_off = 0;
  double median_px = 0, p95_px = 0, max_px = 0;  // full dots vs (cx, cy)
  std::map<int, std::vector<double>> full_errors_by_frame;  // px, per frame
  // Whole dots (files with the `whole` column): per cosine bin, and those
  // at cosine >= 0.15 together (the target).
  bool has_whole = false;
  WholeDotBin whole_bins[kNumCosBins];
  WholeDotBin whole_from_015;
  double FullRecall() const { return full ? static_cast<double>(full_named) / full : 0; }
  double PartialRecall() const { return partial ? static_cast<double>(partial_named) / partial : 0; }
  double PartialHalfRecall() const {
    return partial_half ? static_cast<double>(partial_half_named) / partial_half : 0;
  }
  double HiddenFraction() const { return hidden ? static_cast<double>(hidden_rows) / hidden : 0; }
  double WrongFraction() const { return rows ? static_cast<double>(wrong) / rows : 0; }
  std::string BriefReport() const;
  std::string WholeReport() const;  // the cosine bins; empty without them
};

TrackScore ScoreTracks(const std::vector<Track2d>& tracks, const std::vector<Dot2dTruth>& truth,
                       double wrong_px = 2);

}  // namespace hmc
