#include "blending/correction_smoothing.h"

#include <cmath>
#include <limits>

namespace hmc {

std::vector<double> CorrectionLambdaGrid() {
  std::vector<double> grid;
  for (int i = -4; i <= 16; ++i) grid.push_back(std::pow(10.0, i / 4.0));
  grid.push_back(std::numeric_limits<double>::infinity());
  return grid;
}

std::pair<int, double> ChooseCorrectionSmoothing(
    const std::vector<KernelSmoother>& smoothers, CorrectionBases* cache,
    const std::vector<const std::vector<char>*>& observed,
    const std::vector<std::vector<Vec3>>& residuals, bool use_cp,
    double sigma, KernelFit* best_fit) {
  const std::vector<double> grid = CorrectionLambdaGrid();
  std::pair<int, double> best_choice{0, grid.back()};
  double best = std::numeric_limits<double>::infinity();
  for (size_t w = 0; w < smoothers.size(); ++w) {
    std::vector<const KernelSmoother::Basis*> basis_of;
    std::vector<Eigen::MatrixXd> z;
    for (size_t i = 0; i < residuals.size(); ++i) {
      const KernelSmoother::Basis& basis = cache->Get(w, *observed[i]);
      basis_of.push_back(&basis);
      z.push_back(basis.vectors.transpose() *
                  smoothers[w].Data(basis, residuals[i]));
    }
    for (double lambda : grid) {
      KernelFit fit;
      for (size_t i = 0; i < residuals.size(); ++i) {
        fit.Add(smoothers[w].Fit(*basis_of[i], z[i], lambda));
      }
      const double score = use_cp ? fit.Cp(sigma) : fit.Gcv();
      if (score < best) {
        best = score;
        best_choice = {static_cast<int>(w), lambda};
        *best_fit = fit;
      }
    }
  }
  return best_choice;
}

}  // namespace hmc
