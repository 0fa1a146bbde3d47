// Step 2 of the robust solve (blending/robust_solver.h): the marker noise,
// given or estimated from the global fit's residuals, and the noise the
// local choice of step 3 allows for.
#include <algorithm>
#include <cmath>
#include <vector>

#include "blending/correction_smoothing.h"
#include "blending/robust_solver.h"
#include "blending/robust_solver_state.h"
#include "core/error_stats.h"

namespace hmc {

void RobustSolver::EstimateNoise(Sequence* seq) const {
  const int K = data_.num_bundles;
  const std::vector<Work>& work = seq->work;
  const std::vector<int>& good = seq->good;
  RobustReport& report = seq->report;
  // Step 2: the noise level, from the global fit's residuals when not given.
  std::vector<std::vector<Vec3>>& global_residual = seq->global_residual;
  global_residual.resize(good.size());
  for (size_t i = 0; i < good.size(); ++i) {
    const Work& wk = work[good[i]];
    global_residual[i].assign(K, Vec3::Zero());
    for (int k = 0; k < K; ++k) {
      if (wk.observed[k]) {
        global_residual[i][k] =
            wk.disp[k] - global_.SiteDisplacement(k, wk.global);
      }
    }
  }
  double& sigma = seq->sigma;
  sigma = options_.noise_mm;
  if (sigma < 0) {
    report.noise_estimated = true;
    sigma = 0;
    if (!good.empty()) {
      KernelFit fit;
      ChooseCorrectionSmoothing(smoothers_, &seq->bases, seq->good_observed, global_residual,
                      false, 0.0,
                      &fit);
      sigma = std::sqrt(fit.NoiseVariance());
    }
  }
  report.noise_mm = sigma;

}

// The noise the choice of step 3 allows for: when estimated, also bounded
// by the median over bundles of the better model's neighbourhood error per
// coordinate, min(cost_lgi / 3 (m - 1), cost_global / 3 m), from the
// current global residuals. The global fit's residual counts expressions
// the dataset lacks as noise (held-out frames without noise estimate
// 0.2 mm); where lgi explains the neighbours exactly, this bound is 0.
double RobustSolver::ChoiceNoiseVariance(const Sequence& seq) const {
  const int K = data_.num_bundles;
  const double sigma = seq.sigma;
  const std::vector<Work>& work = seq.work;
  const std::vector<int>& good = seq.good;
  const SolveResult& result = seq.result;
  const std::vector<std::vector<Vec3>>& global_residual = seq.global_residual;
  const double s2 = sigma * sigma;
  if (options_.noise_mm >= 0) return s2;
  std::vector<double> v;
  for (size_t i = 0; i < good.size(); ++i) {
    const Work& wk = work[good[i]];
    const FrameSolve& fs = result.frames[good[i]];
    for (int k = 0; k < K; ++k) {
      if (!wk.observed[k]) continue;
      int m = 0;
      const double cg = NeighbourhoodEnergy(global_residual[i], wk, k, &m);
      if (m < 2) continue;
      v.push_back(std::min(fs.bundles[k].cost / (3.0 * (m - 1)),
                           cg / (3.0 * m)));
    }
  }
  if (v.empty()) return s2;
  return std::min(s2, UpperMedian(&v));
}

}  // namespace hmc
