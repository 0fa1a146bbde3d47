// The `robust` solve, `hmc solve`'s default: local geometric indexing where
// the local data explain the markers better than a global fit can, a bounded
// global blendshape fit where they do not, and a smoothing spline for the
// residual that the marker noise does not explain (docs/method.md, "The
// robust default", gives the measurements behind each step).
//
// Per frame (unskinned shapes and bundles, as lgi; d_k the observed
// displacement of bundle k's surface point):
//   1. lgi's per-bundle choice u_k (blending/lgi_solver.h, steps 1-5) and
//      the bounded global fit w (blending/baseline_blendshape.h) with its
//      residuals r_k = d_k - B_k w.
//   2. The marker noise sigma (std per coordinate): given, or estimated from
//      the global fit's residuals of the whole sequence by generalised
//      cross-validation of a Gaussian-kernel smoother
//      (blending/kernel_smoother.h): sigma^2 = RSS / (3 tr(I - H)) at the
//      chosen width and smoothing.
//      The global fit is then solved again with a ridge per shape,
//      sum_n r_n w_n^2, r_n = s^2 / tau_n^2 from the Gaussian prior
//      w_n ~ N(0, tau_n^2) that maximises the evidence of the sequence's
//      frames (empirical Bayes with automatic relevance determination): the
//      bounded fit alone follows the noise; the prior averages it out and
//      holds back the shapes the sequence does not use. Its noise s is
//      sigma when given; when estimated, the one the evidence prefers, but
//      at least the choice's noise sigma_c of step 3 (from the unridged
//      fit): a noise-free take leaves the global fit a misfit that
//      cross-validation reads as noise and the evidence does not, while the
//      evidence's one-variance model underestimates real noise.
//   3. Per bundle, lgi's choice replaces the global weights where it
//      explains the bundle's neighbourhood (itself and its natural
//      neighbours) better than the global fit by more than the noise can:
//        cost_lgi + margin * 3 sigma^2 * m <= sum_{j in nbhd} |r~_j|^2 + tie,
//      with m the observed bundles of the neighbourhood, tie = m *
//      solve.tie_mm2, and r~_j = (I - H_jj)^-1 r_j the global fit's
//      residual left out one bundle at a time (H: its hat matrix over the
//      shapes inside their bounds, BlendshapeSolver::LeaveOneOutResiduals):
//      cost_lgi is a prediction (lgi's simplex passes through bundle k and
//      is scored on the neighbours), so the global fit is scored by
//      prediction too, not by the residuals it was fitted to. When sigma is
//      estimated, the sigma of this test is
//      also bounded by the median over bundles of the better model's
//      neighbourhood error, min(cost_lgi / 3 (m - 1), cost_global / 3 m):
//      the global fit's residual counts expressions the dataset lacks as
//      noise, lgi's does not where it explains the neighbours. Noise-free, the better of the two wins, and lgi where
//      both are exact (a dataset shape: lgi reproduces it everywhere, the
//      global fit only at the bundles); under noise, only local structure
//      larger than the noise switches to lgi.
//   3b. Temporal coherence (blending/temporal_coherence.h): each bundle's
//      answer of step 3 replaced by its centred moving average over the
//      neighbouring frames where it is not exact and the average explains
//      its neighbourhood as well as the noise allows (within
//      temporal_tolerance noise variances per bundle): the hard per-bundle switches between lgi and the global fit,
//      and between lgi's candidates, no longer flicker.
//   4. Natural-neighbour blend of the per-bundle weights: x*(v) = x0(v) +
//      sum_k lambda_k(v) (global_k ? sum_n w_n b*_n(v) : sum_n u_kn b*_n(v)).
//   5. The blend's residuals at the bundles (measured on the skinned
//      output, taken back to unskinned space by the site's skinning matrix)
//      are first shrunk by what the noise explains: bundle k's residual is
//      scaled by max(0, 1 - 3 sigma_c^2 m / sum_{j in nbhd} |r_j|^2)
//      (positive-part James-Stein; sigma_c the noise of step 3). Then a
//      Gaussian-kernel smoother (blending/kernel_smoother.h) is fitted to
//      them with one width and smoothing for the sequence, by Mallows' C_p
//      for the given sigma, or when estimated for max(sigma_c, the noise
//      generalised cross-validation implies; the smoothings run up to
//      none at all): noise-free data with
//      expressions the dataset lacks are then smoothed as cross-validation
//      predicts best between the bundles, noisy data are not followed. The
//      correction fades away from the bundles, leaving the far field to the
//      dataset. Per frame, the kernel is dropped where its leave-one-out
//      error at the bundles is no lower than none's (it would spread a few
//      isolated residuals between the markers).
//      What is then left at each bundle, e_k = r_k - f(s_k) (r_k before
//      shrinking, f the kernel fit), is soft-thresholded at the noise's
//      universal threshold, tau = sigma_c sqrt(3 * 2 ln 3K) (Donoho &
//      Johnstone 1994: noise alone rarely exceeds it), and interpolated
//      with the sewing's own weights, sum_k lambda_k(v) e_k: bundle k's
//      local surface moved onto the bundle. Noise-free (sigma_c = 0) the
//      surface passes through every bundle again, projected ones included.
//   6. Skin with the frame's jaw pose.
// Bad frames follow the lgi conventions (flagged, previous good mesh kept).
// Each step's code is in the file named after it (robust_global_fit.cc,
// robust_noise.cc, robust_local_choice.cc, robust_temporal.cc,
// robust_correction.cc, robust_blend.cc; docs/method.md "The robust
// default" lists them); robust_solver.cc runs them in order.
#pragma once

#include <map>
#include <string>
#include <vector>

#include <Eigen/SparseCore>

#include "blending/baseline_blendshape.h"
#include "blending/kernel_smoother.h"
#include "blending/lgi_solver.h"
#include "blending/natural_neighbour.h"
#include "core/options.h"

namespace hmc {

struct RobustOptions {
  double noise_mm = -1.0;  // marker noise, std per coordinate (mm); < 0:
                           // estimated from the data
  bool local = true;       // use lgi's local choice where it explains the
                           // neighbourhood better (false: global fit only)
  double margin = 1.0;     // lgi must beat the global fit's neighbourhood
                           // cost by this many noise variances per bundle
  double ridge = -1.0;     // the global fit's ridge, every shape (mm^2 per
                           // unit of weight^2); < 0: one per shape, chosen
                           // from the data
  bool correct = true;     // kernel correction of the residual
  double smoothing = 0.0;  // the correction's lambda (> 0: fixed; 0: chosen
                           // from the data)
  int temporal_window = 0;  // step 3b: frames of the moving average of each
                            // bundle's answer (<= 1: off, the default:
                            // docs/method.md "Temporal coherence")
  double temporal_tolerance = 0.5;  // step 3b: the average may explain the
                                    // neighbourhood this many noise
                                    // variances per bundle worse
  std::string take = "auto";  // whether the frames are a take (steps 3b
                              // and 3c run only on one): auto (by the lag-1
                              // correlation of the markers), yes, no
  int correction_window = 5;  // step 5 on a take: frames over which the
                              // residuals are averaged before the
                              // correction's fit (<= 1: off)
  int detail_window = 5;      // step 3c on a take: frames of the moving
                              // average of each bundle's local detail
                              // (<= 1: off)
  int global_shapes = 128;  // the global fit (steps 1, 2b) over at most
                            // this many dataset shapes, those that span
                            // the data at the bundles (SelectSpanningShapes
                            // in blending/baseline_blendshape.h); 0: every
                            // shape
  bool interpolate = true; // then interpolate, with the natural-neighbour
                           // weights, what is left at each bundle beyond
                           // the noise's threshold (step 5)

  void Register(OptionFields* fields);
  bool Check() const;
};

// What one sequence solve estimated, returned with its result
// (SolveResult::report holds it as named values; SolveSequence's `report`
// argument gets it typed).
struct RobustReport {
  double noise_mm = 0.0;      // sigma used (given or estimated)
  double selection_noise_mm = 0.0;  // sigma the choice of step 3 allowed
  double prior_noise_mm = 0.0;      // the noise of the shape prior (step 2)
  bool noise_estimated = false;
  double ridge = 0.0;         // of the global fit, per shape: the median
                              // (mm^2 per weight^2)
  double ridge_min = 0.0;     // and the smallest
  std::vector<double> shape_ridge;  // each of the global fit's shapes'
  double width_mm = 0.0;      // Gaussian width of the correction (mm)
  double lambda = 0.0;        // its smoothing (0: no correction)
  int frames_uncorrected = 0; // good frames it left out (leave-one-out)
  double threshold_mm = 0.0;  // the interpolation's threshold (step 5)
  int64_t bundles_interpolated = 0;  // bundle-frames left beyond it
  int global_shapes = 0;      // the shapes the global fit is over
  int64_t bundles_local = 0;  // observed bundles that took lgi's choice
  int64_t bundles_global = 0;
  int64_t bundles_smoothed = 0;  // bundle-frames that took the temporal
                                 // average (step 3b)
  double take_correlation = 0.0;  // lag-1 correlation of the markers
  bool take = false;              // the frames were treated as a take
  int64_t details_smoothed = 0;   // bundle-frames of step 3c
  double correction_noise_kept = 1.0;  // step 5 on a take: the share of the
                                       // residuals' noise variance their
                                       // average keeps (measured)

  // One line, as `hmc solve` logs it.
  std::string BriefReport(bool interpolate, int good_frames) const;
  // Named values for SolveResult::report (shape_ridge left out: N numbers).
  MethodReport ToMethodReport(bool interpolate, int good_frames) const;
};

class RobustSolver {
 public:
  // All referenced objects must outlive the solver; global must be bounded.
  RobustSolver(const TriMesh& neutral, const ShapeData& data,
               const LgiSolver& lgi, const NaturalNeighbourWeights& nn,
               const BlendshapeSolver& global,
               const SolveOptions& solve_options,
               const RobustOptions& options);

  // Same inputs, outputs and bad-frame conventions as
  // LgiSolver::SolveSequence. Each bundle's weights are its lgi choice or
  // the global weights; the residuals are the output mesh's. The result's
  // report is the RobustReport's values; `report` (optional) gets it typed.
  // sink (optional): each mesh goes to it as its batch is blended, and the
  // result holds none (frame_solve.h, MeshSink).
  SolveResult SolveSequence(const std::vector<BundleFrame>& frames,
                            const std::vector<JawPose>& jaw,
                            const std::vector<std::string>& frame_errors = {},
                            RobustReport* report = nullptr,
                            const MeshSink* sink = nullptr);

 private:
  struct Work;
  struct Sequence;
  // The steps of SolveSequence (this header's top comment numbers them),
  // each on the sequence's state.
  // Step 1: lgi's choices frame by frame and the bounded global fit.
  void SolveLgiAndGlobal(const std::vector<BundleFrame>& frames,
                         const std::vector<JawPose>& jaw,
                         const std::vector<std::string>& frame_errors,
                         Sequence* seq) const;
  // Step 2: the marker noise, from the global fit's residuals unless given.
  void EstimateNoise(Sequence* seq) const;
  // The noise variance the choice of step 3 allows for (mm^2).
  double ChoiceNoiseVariance(const Sequence& seq) const;
  // Step 2b: the global fit again with the per-shape ridge, and its
  // leave-one-out residuals.
  void FitShapePrior(Sequence* seq) const;
  // Step 3: per bundle, lgi's choice or the global weights.
  void ChooseLocalOrGlobal(Sequence* seq) const;
  // Step 3b: each bundle's answer averaged over neighbouring frames where
  // the average still explains the frame (blending/temporal_coherence.h).
  void SmoothAnswersInTime(Sequence* seq) const;
  // Whether the sequence is a take (options_.take; auto: by the lag-1
  // correlation of its markers), recorded in the report.
  bool IsTake(Sequence* seq) const;
  // Step 3c: each bundle's local detail averaged over neighbouring frames
  // of a take (blending/temporal_coherence.h).
  void SmoothDetailInTime(Sequence* seq) const;
  // Step 5: the correction's width and smoothing (caches the kernel).
  void ChooseCorrection(Sequence* seq);
  // Step 5: what the correction leaves beyond the threshold, interpolated.
  void InterpolateBeyondThreshold(Sequence* seq) const;
  // Steps 4-6: the blend of every good frame; bad frames filled. With a
  // sink, each mesh goes to it instead of the result.
  void BlendFrames(Sequence* seq, const MeshSink* sink) const;
  // sum |r_j|^2 over observed bundle k and its observed natural neighbours;
  // *count: how many.
  double NeighbourhoodEnergy(const std::vector<Vec3>& r, const Work& work,
                             int k, int* count) const;
  // The unskinned blend at vertex v (step 4).
  Vec3 BlendVertex(const Work& work, const FrameSolve& frame, int v) const;
  // Steps 4-6 for up to kBlendBatch good frames at once, so that each
  // vertex's shape displacements are read from memory once per batch: the
  // unskinned blend plus the correction of step 5, sum_k kernel(v, k)
  // alpha_k (the frame's Work::alpha, when kernel is given) + sum_k
  // lambda_k(v) e_k (Work::offset), skinned by the frame's jaw when the
  // actor has a jaw rig (as Skin). V x 3 per frame.
  static constexpr int kBlendBatch = 8;
  std::vector<MatX3d> BlendBatch(
      const std::vector<const Work*>& work,
      const std::vector<const FrameSolve*>& frames,
      const Eigen::SparseMatrix<double, Eigen::RowMajor>* kernel) const;

  const TriMesh& neutral_;
  const ShapeData& data_;
  const LgiSolver& lgi_;
  const NaturalNeighbourWeights& nn_;
  const BlendshapeSolver& global_;
  SolveOptions solve_options_;
  RobustOptions options_;
  // Smoothers of the candidate widths (kWidthScales marker spacings) and,
  // once a width was chosen, its kernel at the vertices (V x K).
  std::vector<KernelSmoother> smoothers_;
  std::map<int, Eigen::SparseMatrix<double, Eigen::RowMajor>> vertex_kernel_;
};

}  // namespace hmc
