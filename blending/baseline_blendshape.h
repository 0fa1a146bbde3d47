// The `blendshape` and `blendshape-bounded` baselines (docs/baselines.md):
// one set of weights over ALL dataset shapes, fitted so the bundles' surface
// points land on the observed positions -- what a rig solver does. Same
// inputs and outputs as the lgi solve (blending/lgi_solver.h): per frame,
// bundles by marker name and a jaw pose in, a V x 3 mesh and a FrameSolve
// out; bad frames are flagged and repeat the previous good mesh.
//
// With a jaw rig the fit runs on unskinned shapes and unskinned bundles
// (indexing/shape_data.h, as lgi does) and the result is skinned with the
// frame's jaw pose, so the comparison with lgi is like for like.
//
// Objective over weights w (N), bundle displacements d_k = p*_k - x0(s_k),
// shapes at the sites B_k (3 x N):
//   E(w) = sum_k |B_k w - d_k|^2 + lambda |w|^2
//          + mu sum_n (max(0, -w_n)^2 + max(0, w_n - 1)^2)      (soft)
// or the first two terms subject to 0 <= w <= 1                   (bounded).
// The soft objective is convex and piecewise quadratic: Newton steps on the
// current active penalty sets with a backtracking line search reach its
// minimum in a few iterations. The bounded one is a box-constrained QP,
// solved by projected Newton (Bertsekas 1982, "Projected Newton methods for
// optimization problems with simple constraints"). The normal matrix
// H = sum_k B_k^T B_k + lambda I is precomputed once per actor; a frame with
// missing bundles subtracts their rank-3 terms.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <string>
#include <unordered_map>
#include <vector>

#include "blending/lgi_solver.h"
#include "core/frame_data.h"
#include "core/mesh.h"
#include "core/options.h"
#include "indexing/shape_data.h"

namespace hmc {

struct BlendshapeOptions {
  bool bounded = false;      // hard bounds 0 <= w <= 1 instead of the penalty
  double penalty = 100.0;    // mu: weight of the soft [0,1] penalty
                             // (mm^2 per unit of weight^2)
  double tikhonov = 1e-6;    // lambda: |w|^2 regulariser for conditioning
                             // (mm^2 per unit of weight^2)
  int max_iterations = 100;  // solver iterations per frame (Newton steps;
                             // active-set updates when bounded)
  double min_bundle_fraction = 0.5;  // frames with fewer observed bundles
                                     // (fraction of markers) are bad; not
                                     // registered: `hmc solve` sets it from
                                     // solve.min_bundle_fraction
  int max_shapes = 0;  // > 0: fit over at most this many dataset shapes,
                       // SelectSpanningShapes's (0: every shape); not
                       // registered: the robust default sets it from
                       // robust.global_shapes

  void Register(OptionFields* fields);
  bool Check() const;
};

// min 1/2 w^T Q w - c^T w + 1/2 mu sum_n (max(0,-w_n)^2 + max(0,w_n-1)^2).
// Q: N x N symmetric positive definite; c: N. Returns N weights.
Eigen::VectorXd SolveSoftBoxQp(const Eigen::MatrixXd& Q,
                               const Eigen::VectorXd& c, double mu,
                               int max_iterations);
// min 1/2 w^T Q w - c^T w subject to 0 <= w <= 1. Q: N x N symmetric
// positive definite; c: N. Returns N weights in [0, 1]. start (optional,
// N): a guess of the solution (clamped to the box), from which the bounds
// are corrected one at a time.
Eigen::VectorXd SolveBoundedBoxQp(const Eigen::MatrixXd& Q,
                                  const Eigen::VectorXd& c, int max_iterations,
                                  const Eigen::VectorXd* start = nullptr);

// The dataset shapes a global fit over at most max_shapes of them uses
// (indices, ascending; docs/method.md "A global fit of bounded size"):
// every shape when N <= max_shapes (or max_shapes <= 0); else, in the
// dataset's order, each shape whose displacement at the bundles (column n
// of site_shapes, 3K x N) keeps more than min_new of its norm outside the
// span of the shapes kept before it, until max_shapes are kept. Shapes
// that do not move the bundles are never kept then. Every dataset shape is
// then within min_new (relative) of the kept shapes' span at the bundles,
// unless the cap was reached.
std::vector<int> SelectSpanningShapes(const Eigen::MatrixXd& site_shapes,
                                      int max_shapes, double min_new);

// Runs a per-frame baseline over a sequence with the lgi conventions
// (LgiSolver::SolveSequence): frame_errors (empty or one per frame) marks
// frames bad; a bad frame, or one `solve` returns !ok, repeats the previous
// good mesh (the jaw-skinned neutral before the first good one). `solve`
// gets the frame's position in `frames` and fills its mesh when ok. jaw: one
// pose per frame, or empty. Frames are solved in order, one at a time (each
// solve is parallel inside).
using BaselineFrameFn = std::function<FrameSolve(int index, const BundleFrame&,
                                                 const JawPose&, MatX3d*)>;
SolveResult RunBaselineSequence(const ShapeData& data, const TriMesh& neutral,
                                const std::vector<BundleFrame>& frames,
                                const std::vector<JawPose>& jaw,
                                const std::vector<std::string>& frame_errors,
                                const BaselineFrameFn& solve,
                                const std::string& name);

// Weights are over the solver's shapes (N below is num_shapes(), their
// dataset indices shapes()): every dataset shape unless options.max_shapes
// selects fewer.
class BlendshapeSolver {
 public:
  // neutral (V x 3, triangles) and data must outlive the solver.
  BlendshapeSolver(const TriMesh& neutral, const ShapeData& data,
                   const BlendshapeOptions& options);

  // The shapes the weights are over: how many, and their dataset indices
  // (ascending).
  int num_shapes() const { return static_cast<int>(shapes_.size()); }
  const std::vector<int>& shapes() const { return shapes_; }

  // Fits the weights for one frame; on success fills *weights (N) and, if
  // mesh is given, the skinned result (V x 3) and each bundle's residual.
  // start (optional, N): a guess of the weights (the previous frame's) that
  // the bounded fit tries first; the result does not depend on it.
  FrameSolve SolveFrame(const BundleFrame& bundles, const JawPose& jaw,
                        Eigen::VectorXd* weights, MatX3d* mesh,
                        const Eigen::VectorXd* start = nullptr) const;

  // The normal matrix over the observed bundles (K flags): sum_k B_k^T B_k
  // + lambda I (N x N).
  Eigen::MatrixXd Normal(const std::vector<char>& observed) const;
  // B^T d for unskinned displacements d (3K, zero where not observed).
  Eigen::VectorXd Project(const Eigen::VectorXd& d) const {
    return site_shapes_.transpose() * d;
  }
  // The weights (N) fitted to d (3K, zero where not observed) with one
  // ridge per shape (N) added to the normal matrix's diagonal (mm^2 per unit
  // of weight^2): a Gaussian prior of variance sigma^2 / ridge_n pulling
  // weight n toward the neutral. start: as SolveFrame's.
  Eigen::VectorXd FitWeights(const std::vector<char>& observed,
                             const Eigen::VectorXd& d,
                             const Eigen::VectorXd& ridge,
                             const Eigen::VectorXd* start = nullptr) const;

  // Each observed bundle's residual as the fit without that bundle would
  // leave it (leave one out), for weights from FitWeights with these ridges
  // (N; bounded fit only): over the shapes strictly inside their bounds F
  // (the others held at their bound),
  // H = B_F (B_F^T B_F + lambda I + diag(ridge_F))^-1 B_F^T and
  // r_k^(-k) = (I - H_kk)^-1 r_k, exact for that fit with its active bounds
  // held. residual: K residuals r_k = d_k - B_k w (observed ones
  // used); returns K (zero where not observed).
  std::vector<Vec3> LeaveOneOutResiduals(const std::vector<char>& observed,
                                         const Eigen::VectorXd& weights,
                                         const Eigen::VectorXd& ridge,
                                         const std::vector<Vec3>& residual) const;

  // The unskinned displacement sum_n w_n b*_n(s_k) of bundle k's surface
  // point (mm). weights: N.
  Vec3 SiteDisplacement(int k, const Eigen::VectorXd& weights) const {
    return site_shapes_.middleRows<3>(3 * k) * weights;
  }

  // x = Skin(x0 + sum_n w_n b*_n, jaw): V x 3 (mm). weights: N.
  MatX3d Blend(const Eigen::VectorXd& weights, const JawPose& jaw) const;

  // All frames; `weights` (optional) receives each frame's weights (empty
  // for bad frames).
  SolveResult SolveSequence(
      const std::vector<BundleFrame>& frames, const std::vector<JawPose>& jaw,
      const std::vector<std::string>& frame_errors = {},
      std::vector<Eigen::VectorXd>* weights = nullptr) const;

 private:
  const TriMesh& neutral_;
  const ShapeData& data_;
  BlendshapeOptions options_;
  std::unordered_map<std::string, int> marker_index_;
  std::vector<int> shapes_;      // the dataset indices of the N shapes
  Eigen::MatrixXd site_shapes_;  // 3K x N: rows 3k..3k+2 are B_k
  Eigen::MatrixXd normal_;       // N x N: sum_k B_k^T B_k + lambda I
};

}  // namespace hmc
