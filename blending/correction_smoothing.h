// Step 5 of the robust default (blending/robust_solver.h, docs/method.md
// "The robust default"): the choice of the correction's smoothing. The
// correction is a Gaussian-kernel smoother (blending/kernel_smoother.h) of
// the blend's residuals at the bundles, with one width and one smoothing for
// the whole sequence, chosen here from a small grid by Mallows' C_p for a
// known noise or by generalised cross-validation (which also gives the noise
// estimate of step 2).
#pragma once

#include <map>
#include <utility>
#include <vector>

#include "blending/kernel_smoother.h"
#include "core/types.h"

namespace hmc {

// The correction's candidate widths, in marker spacings (the median
// distance of a bundle's site to its nearest site), and smoothings (the
// kernel is 1 on its diagonal): log-spaced from interpolation of exact data
// to nearly none, then none at all (infinity: the residual is left as it
// is, and the blend skips the kernel).
constexpr double kCorrectionWidthScales[] = {1.0, 2.0};
std::vector<double> CorrectionLambdaGrid();

// The kernel decompositions of one sequence, per width and observed set
// (frames usually share one set), each computed once.
class CorrectionBases {
 public:
  explicit CorrectionBases(const std::vector<KernelSmoother>& smoothers)
      : smoothers_(smoothers), bases_(smoothers.size()) {}
  const KernelSmoother::Basis& Get(size_t width,
                                   const std::vector<char>& observed) {
    auto found = bases_[width].find(observed);
    if (found == bases_[width].end()) {
      found = bases_[width]
                  .emplace(observed, smoothers_[width].MakeBasis(observed))
                  .first;
    }
    return found->second;
  }
  // Frees every decomposition (a long shot has hundreds of observed sets).
  void Clear() {
    for (auto& per_width : bases_) per_width.clear();
  }

 private:
  const std::vector<KernelSmoother>& smoothers_;
  std::vector<std::map<std::vector<char>, KernelSmoother::Basis>> bases_;
};


// The best (width index, lambda) for the residuals of every good frame
// (K entries each, over the frame's observed bundles), by C_p for a known
// sigma, else by generalised cross-validation; *fit receives the pooled fit
// there.
std::pair<int, double> ChooseCorrectionSmoothing(
    const std::vector<KernelSmoother>& smoothers, CorrectionBases* cache,
    const std::vector<const std::vector<char>*>& observed,
    const std::vector<std::vector<Vec3>>& residuals, bool use_cp,
    double sigma, KernelFit* best_fit);

}  // namespace hmc
