// Step 3b of the robust default (blending/robust_solver.h, docs/method.md
// "The robust default", "Temporal coherence"): the per-bundle answers of
// step 3 (lgi's local weights or the global fit's), smoothed in time where
// the smoothed answer still explains the frame.
//
// Step 3 picks, per bundle and frame, one of two answers, and lgi picks one
// of its candidates: on expressions the dataset lacks, or under noise, the
// pick changes from frame to frame between answers that explain the markers
// about equally well but differ between them, and the skin between the
// markers shimmers (issue 23: 5.5x the blendshape solve's flicker on a
// production-style take). Here each bundle's weights w_f (relative to the
// neutral, unskinned, as the paper's temporal smoothing) are replaced by
// their centred moving average over the good frames of a window,
//   w~_f = sum_{|g - f| <= h} t_{g-f} w_g / sum t   (triangular t),
// when both
//   - the bundle's own answer is not exact: its neighbourhood cost
//     c(w_f) = sum_{j in nbhd(k)} |d_j - B_j w_f|^2 exceeds m tie (an exact
//     answer, e.g. a dataset shape's, stays as it is: verification), and
//   - the average explains the frame's neighbourhood as well as the noise
//     allows: c(w~_f) <= c(w_f) + tolerance 3 sigma^2 m + m tie, sigma the
//     noise of step 3's choice (per coordinate).
// Unrelated consecutive frames (the dataset sequence, random combinations)
// fail the second test; a performance, whose answers change smoothly
// except for the switches, passes it. (A tolerance relative to c(w_f)
// instead, c(w~_f) <= 2 c(w_f), let noisy random combinations average
// unrelated frames: linear actor, 0.5 mm, face mean 0.077 -> 0.121 mm.)
#pragma once

#include <utility>
#include <vector>

#include "core/types.h"
#include "indexing/shape_data.h"

namespace hmc {

struct TemporalCoherenceOptions {
  int window = 5;          // frames of the moving average (<= 1: off)
  double tolerance = 0.5;  // the average's neighbourhood cost may exceed the
                           // answer's by this many noise variances per bundle
  double noise2 = 0.0;     // sigma^2, the noise variance per coordinate (mm^2)
  double tie_mm2 = 1e-10;  // per bundle: costs within m tie are exact
};

// One frame as step 3b sees it. weights: K per-bundle sparse weights (the
// answer of step 3), replaced in place; disp: K unskinned observed
// displacements; observed: K flags; neighbours: per bundle its natural
// neighbours.
struct TemporalFrame {
  std::vector<std::vector<std::pair<int, double>>>* weights = nullptr;
  const std::vector<Vec3>* disp = nullptr;
  const std::vector<char>* observed = nullptr;
};

// Smooths the answers of consecutive frames (the good frames of a sequence,
// in order; a gap in `frame_numbers` of more than one frame breaks the
// window). Returns how many bundle-frames took the average; *changed (K per
// frame, optional) flags them.
int64_t SmoothAnswersInTime(const ShapeData& data,
                            const std::vector<std::vector<int>>& neighbours,
                            const std::vector<int>& frame_numbers,
                            const TemporalCoherenceOptions& options,
                            std::vector<TemporalFrame>* frames,
                            std::vector<std::vector<char>>* changed);

}  // namespace hmc
