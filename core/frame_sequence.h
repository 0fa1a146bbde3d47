// The sequence driver: how every per-frame stage turns F input frames into F
// per-frame results (docs/ARCHITECTURE.md, "Sequence driver"). Generic over
// the stage's per-frame record and result; the solvers (blending/) and the
// per-frame front-end stages (stabilization, jaw, triangulation) share it:
//
//   1. VisitFrames: frames are visited in order, one at a time (a stage may
//      look at the previous frame's result, e.g. lgi's temporal
//      preference). A frame the caller already knows is bad (a non-empty
//      entry of `known_bad`: no bundles, no jaw pose, ...) is not solved:
//      mark_bad(f, reason) records it as a value in the frame's record;
//      every other frame is solve(f)'s, which may itself find the frame bad.
//   2. FillBadFrames: every bad frame's result repeats the previous good
//      frame's (a stage's output stays aligned with frame numbers and never
//      jumps to a default in the middle of a shot); a bad frame before the
//      first good one takes before_first(f). Returns the number of bad
//      frames, for the stage's report.
//
// Per-frame failures are values (the stage's record says why), never
// exceptions (docs/ARCHITECTURE.md, "Contracts").
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "core/error.h"
#include "core/logging.h"

namespace hmc {

// Step 1. known_bad: empty, or one entry per frame (empty = not known bad).
// solve(int f) and mark_bad(int f, const std::string& reason) are called
// once per frame, in frame order. progress_label: the progress line's label.
template <typename Solve, typename MarkBad>
void VisitFrames(int num_frames, const std::vector<std::string>& known_bad,
                 const std::string& progress_label, Solve&& solve,
                 MarkBad&& mark_bad) {
  HMC_CHECK(known_bad.empty() ||
            static_cast<int>(known_bad.size()) == num_frames);
  Progress progress(progress_label, num_frames);
  for (int f = 0; f < num_frames; ++f) {
    if (!known_bad.empty() && !known_bad[f].empty()) {
      mark_bad(f, known_bad[f]);
    } else {
      solve(f);
    }
    progress.Advance();
  }
}

// Step 2. ok(int f): whether frame f is good; before_first(int f) -> T: the
// result of a bad frame before the first good one. Good frames' results are
// left as they are.
template <typename T, typename IsOk, typename BeforeFirst>
int FillBadFrames(IsOk&& ok, BeforeFirst&& before_first,
                  std::vector<T>* results) {
  int last_good = -1, bad = 0;
  for (int f = 0; f < static_cast<int>(results->size()); ++f) {
    if (ok(f)) {
      last_good = f;
      continue;
    }
    ++bad;
    (*results)[f] = last_good >= 0 ? (*results)[last_good] : before_first(f);
  }
  return bad;
}

}  // namespace hmc
