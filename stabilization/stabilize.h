// `hmc stabilize`: per frame, the rigid head_from_helmet that maps the
// frame's helmet-space bundles onto the actor's neutral markers, and the
// bundles in head space (method, weighting and measured accuracy:
// docs/stabilization.md; files: docs/formats.md).
//
// Per frame, with a_k the bundle of marker k in helmet space and q_k the
// marker on the neutral:
//   min_{T, c} sum_k w0_k rho(|T a_k - q_k - B_k c|) + lambda |c|^2
// (stabilization/head_fit.h): the expression c projected out, Gauss-Newton
// on the pose with robust weights renewed every step, to convergence.
//  - Prior weights w0_k from the actor's dataset (`weighting: motion`): the
//    inverse of the variance a marker's position has about the rigid head,
//    w0_k = 1 / (sigma^2 + m_k^2), sigma the assumed bundle noise and m_k
//    the RMS over the dataset's shapes of how far shape n moves marker k
//    (stabilization/marker_model.h); normalised so the largest is 1. A
//    marker no shape moves is trusted, one the brows or cheeks move is not.
//    `tags`: 1 on markers tagged `stable`, 0 elsewhere; `both`: the motion
//    weights on the `stable` markers only.
//  - Expression-aware (`expression: true`): c are global shape weights
//    (B_k the 3 x N skinned shape displacements at marker k) fitted jointly
//    with the pose, so a brow raise or a squint is explained by the shapes
//    and does not tilt the head; a marker the shapes cannot explain (a bad
//    track, a unit the dataset lacks) gets a small robust weight.
//  - Shot weights (`shot_weights: true`): a second pass whose prior weights
//    are w0_k = 1 / (v_k + v_floor), v_k marker k's median squared residual
//    over the first pass's frames and v_floor the median v_k of the markers
//    the dataset trusts (w0 >= 0.5): with the expression explained, the
//    whole face carries information about the head.
//  - A frame with fewer than min_markers usable markers (present, with a
//    prior weight of at least min_weight) or with collinear ones is flagged
//    and its pose interpolated from the nearest good frames (rotation by
//    slerp, translation linearly; held at the ends).
//  - Temporal prior (`temporal_prior: true`): the poses of all frames
//    together, each frame's fit weighted by how well it determines its
//    pose (its residual variance: near zero where the dataset explains the
//    markers) and the pose a random walk between frames whose step size is
//    measured on the shot (stabilization/pose_trajectory.h); a frame with
//    motion the dataset lacks leans on its neighbours.
//  - Optional smoothing: a centred moving average of the poses over
//    smooth_frames frames (slip is slow, vibration is fast: the vibration
//    is real head-helmet motion, so smoothing is off by default).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "core/actor.h"
#include "core/frame_data.h"
#include "core/day_markers.h"
#include "core/options.h"
#include "stabilization/marker_model.h"

namespace hmc {

struct StabilizeOptions {
  std::string weighting = "motion";  // motion | tags | both (see stabilize.h)
  double noise_mm = 0.1;         // sigma: bundle noise assumed by the motion weights (mm)
  std::string loss = "cauchy";   // robust loss of the reweighting: none | huber | cauchy
  double loss_scale_mm = 0.5;    // residual scale of the robust loss (mm)
  bool expression = true;        // fit global shape weights jointly with the pose
  bool shot_weights = true;      // second pass with weights from the first pass's per-marker residuals
  double expression_ridge = 1e-4;  // ridge on the shape weights (mm^2 per unit weight^2)
  int max_iterations = 100;      // reweighting rounds per frame at most
  double tolerance_mm = 1e-4;    // converged: a round of reweighting moves no marker further (mm)
  int min_markers = 4;           // fewer usable markers: the frame is interpolated
  double min_weight = 0.01;      // prior weight (of the largest) a usable marker needs
  double bad_track_mm = 1.0;     // a trusted marker (prior weight >= 0.5) whose median residual exceeds this is reported
  bool temporal_prior = true;    // poses of frames the dataset explains less well informed by their neighbours (see stabilize.h)
  int smooth_frames = 0;         // centred moving-average window over poses (frames; 0 or 1 = off)
  int threads = 0;               // worker threads (0 = all cores)
  DayMarkersOptions day;         // markers: the day's markers (core/day_markers.h)

  void Register(OptionFields* fields);
  bool Check() const;
};

struct MarkerResidual {
  int marker = -1;           // index into the actor's markers
  double residual_mm = 0;    // |T a_k - q_k (- B_k c)| after the fit
  double weight = 0;         // final weight (prior x robust; 0 where not fitted)
};

struct StabilizedFrame {
  int frame = 0;
  Rigid3 head_from_helmet = Rigid3::Identity();
  bool ok = false;           // false: pose interpolated (see reason)
  std::string reason;        // why the frame was not fitted
  int markers_used = 0;      // usable markers present
  double rms_mm = 0;         // weighted RMS residual of the fit (mm)
  int iterations = 0;        // reweighting rounds of the (last pass's) fit
  bool converged = false;    // its last round moved no marker by more than tolerance_mm
  double last_step_mm = 0;   // how far its last round moved the furthest marker (mm)
  Eigen::Matrix<double, 6, 6> information = Eigen::Matrix<double, 6, 6>::Zero();  // of the fit (head_fit.h)
  double prior_move_mm = 0;  // how far the temporal prior moved the furthest marker (mm)
  std::vector<MarkerResidual> residuals;  // every present marker, against the fitted pose
};

struct BadTrack {
  std::string marker;
  double median_residual_mm = 0;
};

struct StabilizeOutput {
  std::vector<StabilizedFrame> frames;
  std::vector<BundleFrame> bundles;   // head space, every present marker
  std::vector<BadTrack> bad_tracks;
  std::vector<std::string> unknown_markers;  // in the bundles, not in the actor
  int num_ok = 0;
  int num_interpolated = 0;
  int num_not_converged = 0;  // fitted frames whose fit stopped at max_iterations
  double prior_move_max_mm = 0;  // the temporal prior's largest move of a marker (mm)
  double mean_rms_mm = 0;     // over fitted frames
  double seconds = 0;
  std::string BriefReport() const;
};

// The prior weights w0 (K, largest 1) of `options.weighting`.
Eigen::VectorXd StabilizationWeights(const MarkerModel& model,
                                     const StabilizeOptions& options);

// Stabilizes every frame (parallel over frames; deterministic). Throws
// InputError for invalid options; bad frames are values.
StabilizeOutput RunStabilize(const MarkerModel& model,
                             const std::vector<BundleFrame>& bundles_helmet,
                             const StabilizeOptions& options);

// Writes head_from_helmet.csv, bundles.csv, residuals.csv,
// options_used.yaml and, last, summary.json to `dir` (created if missing).
void WriteStabilizeOutput(const StabilizeOutput& output,
                          const MarkerModel& model,
                          const StabilizeOptions& options,
                          const std::filesystem::path& dir);

// Fills the poses of frames with !ok from the nearest fitted frames
// (slerp/lerp by frame number; held at the ends; identity if none is ok).
void InterpolateFailedPoses(std::vector<StabilizedFrame>* frames);

}  // namespace hmc
