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

// Whether consecutive frames are a take (a continuous recording) rather
// than unrelated expressions (a dataset's shapes, random combinations):
// the lag-1 correlation of the observed displacements over the sequence,
//   rho = 1 - E|d_k(t+1) - d_k(t)|^2 / (2 Var_t d_k),
// both terms freed of the marker noise (sigma^2 per coordinate: the step
// carries 2 x 3 sigma^2 of it, the variance 3 sigma^2). Independent frames
// give 0 in expectation, a smooth motion near 1; in a take sampled at the
// frame rate the face moves little from one frame to the next against how
// far it moves over the take. Frames are consecutive where their numbers
// differ by 1; markers count where observed in both frames of a step.
// Returns 0 for fewer than 3 frames.
double LagOneCorrelation(const std::vector<int>& frame_numbers,
                         const std::vector<const std::vector<Vec3>*>& disp,
                         const std::vector<const std::vector<char>*>& observed,
                         double noise2);

// A take's frames are correlated at lag 1 by at least this much: half way
// between independent frames (0) and a motion that does not change from
// frame to frame (1). Measured (docs/method.md, "Takes"): synthetic
// performances at 30 fps 0.76-1, hmc run's tracked shots 0.88-0.95;
// random combinations, held-out and mixed frames -0.16-0.21, a dataset's
// shapes in their order 0.15-0.41.
constexpr double kTakeCorrelation = 0.5;

// Step 3c of the robust default on a take: each bundle's local detail,
// its answer less the frame's global answer (none where it takes the
// global one), replaced by the detail's triangular moving average over
// `window` frames (those consecutive with the frame that observe the
// bundle), added to the frame's own global answer:
//   a_k(f) = w(f) + sum_g t_g [u_k(g) - w(g) if local in g, else 0] / sum_g t_g.
// The global answer is smooth in a take (one fit to every marker, with the
// sequence's shape prior); lgi's answers switch between candidates and the
// global fit from frame to frame, and the skin between the markers
// shimmers. The correction and interpolation of step 5 then fit the blend
// to the markers again. (Averaging the answers themselves, a global one
// counted as the frame's own, measured far worse without noise: linear
// actor seed 1, face mean 0.0146 -> 0.0357 mm against 0.0142 for this.)
struct DetailFrame {
  const std::vector<std::pair<int, double>>* global = nullptr;  // the frame's global answer
  const std::vector<std::vector<std::pair<int, double>>>* answers = nullptr;  // K: lgi's
  const std::vector<char>* use_global = nullptr;  // K: takes the global answer
  const std::vector<char>* observed = nullptr;    // K
  // Out, K: where the window holds a local answer of the bundle, the
  // averaged detail (sorted by shape) to add to the frame's global answer;
  // elsewhere empty and `changed` 0.
  std::vector<std::vector<std::pair<int, double>>>* detail = nullptr;
  std::vector<char>* changed = nullptr;
};

// Returns the bundle-frames that changed.
int64_t SmoothDetailInTime(const std::vector<int>& frame_numbers, int window,
                           std::vector<DetailFrame>* frames);

// Per bundle, the triangular moving average over `window` frames of a
// take (those consecutive with the frame that observe the bundle) of a
// per-bundle vector, e.g. the blend's residual at the markers (step 5 on a
// take: noise averages out, a held-out expression's smooth motion stays).
// *variance_factor (F x K) receives sum t^2 / (sum t)^2, the share of
// independent noise's variance the average keeps (19/81 for 5 frames).
void AverageInTake(const std::vector<int>& frame_numbers,
                   const std::vector<const std::vector<char>*>& observed,
                   const std::vector<std::vector<Vec3>>& values, int window,
                   std::vector<std::vector<Vec3>>* averaged,
                   std::vector<std::vector<double>>* variance_factor);

// AverageInTake's variance factor where the whole window is there (every
// frame consecutive and observed): the least share of independent noise's
// variance the average keeps (19/81 for 5 frames; 1 for window <= 1).
double WholeWindowVarianceFactor(int window);

}  // namespace hmc
