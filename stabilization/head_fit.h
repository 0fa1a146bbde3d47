// The head pose of one frame with the expression fitted jointly
// (docs/stabilization.md, "The joint fit").
//
// With a_k the bundle of marker k in helmet space, q_k the marker on the
// neutral, B_k (3 x N) the dataset's displacements of marker k and s_k its
// prior weight, the pose T = head_from_helmet and global shape weights c
// minimise
//   E(T, c) = sum_k s_k rho(|T a_k - q_k - B_k c|) + lambda |c|^2.
// The expression enters linearly, so it is projected out (variable
// projection, Golub & Pereyra 1973): for the current robust weights
// w_k = s_k rho'(r_k) / r_k (W = diag(w) per coordinate) and
// d = T a - q (3n),
//   c(T) = G^-1 B^T W d,   G = B^T W B + lambda I,
//   E(T) = d^T Q d,        Q = W - W B G^-1 B^T W,
// and Gauss-Newton on the 6 pose parameters alone takes, with J the
// 3n x 6 Jacobian of d under a small rotation about the markers' centroid
// and a translation,
//   (J^T Q J) delta = -J^T Q d,
// Q being constant for fixed weights (the reduced problem is an exact
// least-squares problem in T, not an approximation of it). Each round
// solves it for fixed weights, then renews the robust weights from its
// residuals (iteratively reweighted least squares: for Huber and Cauchy a
// majorise-minimise step, so the robust objective never increases), and
// the fit stops when a round moves no marker by more than `tolerance_mm`
// (1e-4 mm: a hundredth of the best accuracy asked of the head pose),
// not after a fixed count of rounds. An alternation of the rigid fit with the
// expression fit instead converges slowly where broad shapes (a brow raise
// up to the hairline, a smile up to the lids) move the markers the head
// is fitted to: its steps shrink by a constant factor near 1.
#pragma once

#include <Eigen/Core>

#include "core/types.h"
#include "stabilization/rigid_fit.h"

namespace hmc {

// The cross-product matrix: Skew(v) * x = v.cross(x).
Mat3 Skew(const Vec3& v);

struct HeadFitOptions {
  RobustLoss loss = RobustLoss::kCauchy;
  double loss_scale_mm = 0.5;    // residual scale of the robust loss (mm)
  double ridge = 1e-4;           // lambda (mm^2 per unit weight^2)
  int max_iterations = 100;      // reweighting rounds at most (and Gauss-Newton steps per round)
  double tolerance_mm = 1e-4;    // converged: the last round moved no marker further (mm)
};

struct HeadFitResult {
  bool ok = false;               // false: fewer than 3 weighted markers, or degenerate
  bool converged = false;        // the last round moved no marker by more than tolerance_mm
  int iterations = 0;            // reweighting rounds taken
  int gauss_newton_steps = 0;    // over all rounds
  double last_step_mm = 0;       // how far the last round moved the furthest marker (mm)
  Rigid3 head_from_helmet = Rigid3::Identity();
  Eigen::VectorXd shape_weights;   // N: c
  Eigen::VectorXd weights;         // n: final s_k rho'(r_k) / r_k
  Eigen::VectorXd residuals_mm;    // n: |T a_k - q_k - B_k c|
  // The inverse of the pose's covariance for independent noise of unit
  // variance per coordinate, H (QJ)^T QJ)^-1 H with H = J^T Q J at the
  // result, for the left perturbation T' = (I + [omega]x) T + v about head
  // space's origin, parameters (omega in rad, v in mm): how well the
  // frame's markers, with the expression projected out, determine its pose.
  Eigen::Matrix<double, 6, 6> information = Eigen::Matrix<double, 6, 6>::Zero();
};

// a, q: 3 x n helmet-space bundles and neutral markers (mm); b: 3n x N, rows
// 3i..3i+2 the displacements of marker i (N may be 0: a rigid fit); s: n
// prior weights >= 0; start: the initial pose; start_residuals_mm (n, or
// empty): residuals of an earlier fit of the same frame, whose robust
// weights the first round takes (a second pass starts where the first
// ended).
HeadFitResult FitHeadAndExpression(const Eigen::Matrix3Xd& a, const Eigen::Matrix3Xd& q,
                                   const Eigen::MatrixXd& b, const Eigen::VectorXd& s,
                                   const Rigid3& start, const HeadFitOptions& options,
                                   const Eigen::VectorXd& start_residuals_mm = {});

}  // namespace hmc
