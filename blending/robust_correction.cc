// Step 5 of the robust solve (blending/robust_solver.h): the correction of
// the blend's residual at the bundles, a Gaussian-kernel smoother of one
// width and smoothing per sequence (blending/correction_smoothing.h), and
// what it leaves beyond the noise's threshold, interpolated.
#include <algorithm>
#include <cmath>
#include <tuple>
#include <vector>

#include <Eigen/Core>
#include <Eigen/LU>

#include "blending/correction_smoothing.h"
#include "blending/robust_solver.h"
#include "blending/robust_solver_state.h"
#include "blending/temporal_coherence.h"
#include "core/jaw.h"
#include "core/parallel.h"

namespace hmc {

// Step 5's width and smoothing, from the blend's residuals at the bundles
// (options_.correct, some good frame): sets seq->width_index and
// seq->lambda (-1 and 0: no correction) and each corrected frame's
// coefficients; keeps each bundle's residual for the interpolation.
void RobustSolver::ChooseCorrection(Sequence* seq) {
  const int K = data_.num_bundles;
  std::vector<Work>& work = seq->work;
  const std::vector<int>& good = seq->good;
  const std::vector<const std::vector<char>*>& good_observed =
      seq->good_observed;
  const SolveResult& result = seq->result;
  RobustReport& report = seq->report;
  CorrectionBases& bases = seq->bases;
  const double sel_sigma2 = seq->sel_sigma2;
  int& width_index = seq->width_index;
  double& lambda = seq->lambda;
  const JawRig* rig = data_.jaw_rig ? &*data_.jaw_rig : nullptr;
  std::vector<std::vector<Vec3>> residuals(good.size());
  ParallelFor(0, static_cast<int64_t>(good.size()), [&](int64_t i) {
    Work& wk = work[good[i]];
    const FrameSolve& fs = result.frames[good[i]];
    wk.residual.assign(K, Vec3::Zero());
    for (int k = 0; k < K; ++k) {
      if (!wk.observed[k]) continue;
      // The residual where the output is: the skinned surface point
      // (each corner with its own jaw weight) against the observed
      // bundle, taken back to unskinned space by the site's skinning
      // matrix. (UnskinBundle's inverse assumes the neutral triangle, so
      // d_k - blend(s_k) would show up to ~0.003 mm even for an exact
      // dataset shape.)
      const SurfacePoint& s = data_.sites[k];
      Vec3 x = Vec3::Zero();
      for (int c = 0; c < 3; ++c) {
        const int v = neutral_.F(s.face, c);
        const Vec3 xv = BlendVertex(wk, fs, v);
        x += s.bary[c] *
             (rig ? SkinPoint(*rig, fs.jaw, xv, rig->weights[v]) : xv);
      }
      const Vec3 r = fs.bundles[k].observed - x;
      if (rig) {
        const double w = data_.site_jaw_weight[k];
        const Mat3 a = (1.0 - w) * Mat3::Identity() +
                       w * rig->Transform(fs.jaw).linear();
        wk.residual[k] = a.partialPivLu().solve(r);
      } else {
        wk.residual[k] = r;
      }
    }
  });
  // On a take, the residuals averaged over neighbouring frames first
  // (options_.correction_window): the noise in them drops to a share q of
  // its variance, a held-out expression's smooth deformation stays; the
  // per-frame rest is the interpolation's (step 5).
  std::vector<std::vector<Vec3>> source(good.size());
  std::vector<std::vector<double>> q(good.size());
  double q_floor = 1.0;  // q of a whole window
  if (report.take && options_.correction_window > 1) {
    std::vector<int> numbers;
    for (int f : good) numbers.push_back(result.frames[f].frame);
    std::vector<std::vector<Vec3>> raw(good.size());
    for (size_t i = 0; i < good.size(); ++i) raw[i] = work[good[i]].residual;
    AverageInTake(numbers, good_observed, raw, options_.correction_window, &source, &q);
    const double q_independent = WholeWindowVarianceFactor(options_.correction_window);
    // How much of the residuals' noise the average really removes: the
    // generalised cross-validation noise of the averaged residuals against
    // that of the frames' own. Independent noise keeps q_independent of
    // its variance; an error that persists over frames (a tracked dot's
    // centroid biased the same way for a while) keeps all of it, and the
    // correction must not take it for signal.
    KernelFit raw_fit, averaged_fit;
    ChooseCorrectionSmoothing(smoothers_, &bases, good_observed, raw, false, 0.0, &raw_fit);
    ChooseCorrectionSmoothing(smoothers_, &bases, good_observed, source, false, 0.0,
                              &averaged_fit);
    const double raw_noise = raw_fit.NoiseVariance();
    q_floor = raw_noise > 0
                  ? std::clamp(averaged_fit.NoiseVariance() / raw_noise, q_independent, 1.0)
                  : 1.0;
    report.correction_noise_kept = q_floor;
    for (auto& row : q) {
      for (double& v : row) v = std::min(1.0, v * q_floor / q_independent);
    }
  } else {
    for (size_t i = 0; i < good.size(); ++i) {
      source[i] = work[good[i]].residual;
      q[i].assign(K, 1.0);
    }
  }
  // Only the residual the noise does not explain: each bundle's is
  // shrunk by its neighbourhood's energy against the noise's,
  // max(0, 1 - 3 sigma^2 sum_j q_j / sum |r_j|^2) (positive-part
  // James-Stein; q_j = 1 without the average).
  ParallelFor(0, static_cast<int64_t>(good.size()), [&](int64_t i) {
    const Work& wk = work[good[i]];
    residuals[i].assign(K, Vec3::Zero());
    for (int k = 0; k < K; ++k) {
      if (!wk.observed[k]) continue;
      int m = 0;
      const double energy = NeighbourhoodEnergy(source[i], wk, k, &m);
      double share = q[i][k];
      for (int j : lgi_.Neighbours(k)) {
        if (wk.observed[j]) share += q[i][j];
      }
      const double noise = 3.0 * sel_sigma2 * share;
      const double keep =
          energy > noise ? 1.0 - noise / energy : 0.0;
      residuals[i][k] = keep * source[i][k];
    }
  });
  KernelFit fit;
  double noise = options_.noise_mm < 0 ? -1.0 : options_.noise_mm * std::sqrt(q_floor);
  if (noise < 0) {
    ChooseCorrectionSmoothing(smoothers_, &bases, good_observed, residuals, false,
                    0.0, &fit);
    noise = std::sqrt(std::max(sel_sigma2 * q_floor, fit.NoiseVariance()));
  }
  std::tie(width_index, lambda) = ChooseCorrectionSmoothing(
      smoothers_, &bases, good_observed, residuals, true, noise, &fit);
  if (options_.smoothing > 0) lambda = options_.smoothing;
  if (std::isinf(lambda)) {
    width_index = -1;  // no correction
    lambda = 0.0;
  } else {
    if (!vertex_kernel_.count(width_index)) {
      vertex_kernel_[width_index] = GaussianKernelMatrix(
          neutral_.V, data_.site_neutral, smoothers_[width_index].width(),
          1e-6);
    }
    report.width_mm = smoothers_[width_index].width();
    // Per frame, the correction only where it predicts each bundle's
    // residual from the other bundles' better than no correction does
    // (leave-one-out): C_p pooled over the sequence measures the error at
    // the bundles, and a frame whose residual is a few isolated bundles
    // (lgi projected them) gains there but loses between the markers.
    const KernelSmoother& smoother = smoothers_[width_index];
    for (size_t i = 0; i < good.size(); ++i) {
      Work& wk = work[good[i]];
      const KernelSmoother::Basis& basis =
          bases.Get(width_index, wk.observed);
      const Eigen::MatrixXd data = smoother.Data(basis, residuals[i]);
      const Eigen::MatrixXd z = basis.vectors.transpose() * data;
      if (options_.smoothing <= 0 &&  // a given smoothing is kept
          smoother.LeaveOneOutRss(basis, z, lambda) >= z.squaredNorm()) {
        ++report.frames_uncorrected;
        continue;
      }
      wk.alpha = smoother.Coefficients(basis, data, lambda);
    }
  }
}

// What the kernel leaves at each bundle beyond the noise's universal
// threshold, interpolated by the blend's own weights.
// (options_.interpolate; after ChooseCorrection).
void RobustSolver::InterpolateBeyondThreshold(Sequence* seq) const {
  const int K = data_.num_bundles;
  std::vector<Work>& work = seq->work;
  const std::vector<int>& good = seq->good;
  RobustReport& report = seq->report;
  const double sel_sigma2 = seq->sel_sigma2;
  const int width_index = seq->width_index;
  const double tau = std::sqrt(sel_sigma2 * 3.0 * 2.0 * std::log(3.0 * K));
  report.threshold_mm = tau;
  for (const int f : good) {
    Work& wk = work[f];
    const Eigen::MatrixXd fitted =
        wk.alpha.size() > 0 ? smoothers_[width_index].AtSites(wk.alpha)
                            : Eigen::MatrixXd::Zero(K, 3);
    wk.offset.assign(K, Vec3::Zero());
    for (int k = 0; k < K; ++k) {
      if (!wk.observed[k]) continue;
      const Vec3 e = wk.residual[k] - fitted.row(k).transpose();
      const double norm = e.norm();
      if (norm <= tau) continue;
      wk.offset[k] = (1.0 - tau / norm) * e;
      ++report.bundles_interpolated;
    }
  }
}

}  // namespace hmc
