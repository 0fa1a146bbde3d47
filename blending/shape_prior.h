// Step 2b of the robust default (blending/robust_solver.h, docs/method.md
// "The robust default"): the shape prior of the global blendshape fit, one
// ridge per shape from the evidence of the sequence's frames (empirical
// Bayes with automatic relevance determination).
#pragma once

#include <vector>

#include <Eigen/Core>

#include "blending/baseline_blendshape.h"

namespace hmc {

// The global fit's ridge per shape, s^2 / tau_n^2: the Gaussian prior
// w_n ~ N(0, tau_n^2) whose variances maximise the evidence (marginal
// likelihood) of the sequence's frames, d = B w + noise of variance s^2 per
// coordinate (empirical Bayes; bounds ignored). At most 256 frames, evenly
// spaced, of at most 32 sets of observed markers (a factorisation each).
//   1. One variance for every shape: in the eigenbasis of the normal matrix
//      H = V diag(s) V^T, c = V^T B^T d has independent coordinates
//      c_i ~ N(0, s^2 s_i + tau^2 s_i^2); tau^2 by a log-spaced search.
//      With sigma_floor >= 0 (the noise was estimated, not given), s^2 is
//      searched too, and the larger of that and sigma_floor is kept: the
//      global fit's residual need not be marker noise (a noise-free take
//      whose expressions the dataset holds leaves ~1 um of misfit, which
//      the prior must not treat as noise), but the one-variance model
//      underestimates real noise (0.37 mm for 0.5 mm), which the choice's
//      noise (sigma_floor) does not.
//   2. From there, one variance per shape (automatic relevance
//      determination; MacKay 1992's fixed point, pooled over frames):
//      tau_n^2 = sum_f mu_fn^2 / sum_f (1 - S_f,nn / tau_n^2), mu_f and S_f
//      the frame's posterior mean and covariance, tau_n^2 kept in
//      [1e-10, 1e4]. Shapes the sequence does not use get a large ridge,
//      those it uses a small one.
// *prior_sigma receives s.
Eigen::VectorXd ChooseShapePrior(
    const BlendshapeSolver& global,
    const std::vector<const std::vector<char>*>& observed,
    const std::vector<Eigen::VectorXd>& disp, double sigma,
    double sigma_floor, int N, double* prior_sigma);

}  // namespace hmc
