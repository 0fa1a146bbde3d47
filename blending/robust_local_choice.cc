// Step 3 of the robust solve (blending/robust_solver.h): per bundle, lgi's
// local choice where it explains the bundle's neighbourhood better than the
// global fit by more than the noise can, else the global weights.
#include <cmath>
#include <vector>

#include "blending/robust_solver.h"
#include "blending/robust_solver_state.h"

namespace hmc {

double RobustSolver::NeighbourhoodEnergy(const std::vector<Vec3>& r,
                                         const Work& work, int k,
                                         int* count) const {
  double energy = r[k].squaredNorm();
  *count = 1;
  for (int j : lgi_.Neighbours(k)) {
    if (!work.observed[j]) continue;
    energy += r[j].squaredNorm();
    ++*count;
  }
  return energy;
}

void RobustSolver::ChooseLocalOrGlobal(Sequence* seq) const {
  const int K = data_.num_bundles;
  std::vector<Work>& work = seq->work;
  const std::vector<int>& good = seq->good;
  SolveResult& result = seq->result;
  RobustReport& report = seq->report;
  const std::vector<std::vector<Vec3>>& global_loo = seq->global_loo;
  // Step 3: per bundle, lgi's choice or the global weights.
  seq->sel_sigma2 = ChoiceNoiseVariance(*seq);
  const double sel_sigma2 = seq->sel_sigma2;
  report.selection_noise_mm = std::sqrt(sel_sigma2);
  const double per_bundle = options_.margin * 3.0 * sel_sigma2;
  for (size_t i = 0; i < good.size(); ++i) {
    Work& wk = work[good[i]];
    FrameSolve& fs = result.frames[good[i]];
    wk.use_global.assign(K, 1);
    for (int k = 0; k < K; ++k) {
      if (!wk.observed[k]) continue;
      int m = 0;
      const double cost_global =
          NeighbourhoodEnergy(global_loo[i], wk, k, &m);
      if (options_.local && fs.bundles[k].cost + per_bundle * m <=
                                cost_global + m * solve_options_.tie_mm2) {
        wk.use_global[k] = 0;
        ++report.bundles_local;
      } else {
        ++report.bundles_global;
      }
    }
    fs.global_weights = wk.global_nonzero;
    for (int k = 0; k < K; ++k) {
      if (!wk.use_global[k]) continue;
      BundleSolve& b = fs.bundles[k];
      b.weights = {};  // held once, in fs.global_weights
      b.global_share = 1.0;
      b.simplex = -1;
      b.corner_shapes = {};
    }
  }

}

}  // namespace hmc
