// Steps 3b and 3c of the robust solve (blending/robust_solver.h), on a
// take only: each bundle's answer, then its local detail, averaged over the
// neighbouring frames (blending/temporal_coherence.h).
#include <utility>
#include <vector>

#include "blending/robust_solver.h"
#include "blending/robust_solver_state.h"
#include "blending/temporal_coherence.h"

namespace hmc {

bool RobustSolver::IsTake(Sequence* seq) const {
  std::vector<int> numbers;
  std::vector<const std::vector<Vec3>*> disp;
  for (int f : seq->good) {
    numbers.push_back(seq->result.frames[f].frame);
    disp.push_back(&seq->work[f].disp);
  }
  RobustReport& report = seq->report;
  report.take_correlation =
      LagOneCorrelation(numbers, disp, seq->good_observed, seq->sigma * seq->sigma);
  report.take = options_.take == "yes" ||
                (options_.take == "auto" && report.take_correlation >= kTakeCorrelation);
  return report.take;
}

void RobustSolver::SmoothAnswersInTime(Sequence* seq) const {
  if (options_.temporal_window <= 1 || seq->good.size() < 2) return;
  const int K = data_.num_bundles;
  const std::vector<int>& good = seq->good;
  std::vector<std::vector<std::vector<std::pair<int, double>>>> weights(
      good.size());
  std::vector<TemporalFrame> frames(good.size());
  for (size_t i = 0; i < good.size(); ++i) {
    const Work& wk = seq->work[good[i]];
    const FrameSolve& fs = seq->result.frames[good[i]];
    weights[i].resize(K);
    for (int k = 0; k < K; ++k) weights[i][k] = fs.Weights(k);
    frames[i] = {&weights[i], &wk.disp, &wk.observed};
  }
  std::vector<std::vector<int>> neighbours(K);
  for (int k = 0; k < K; ++k) neighbours[k] = lgi_.Neighbours(k);
  TemporalCoherenceOptions options;
  options.window = options_.temporal_window;
  options.tolerance = options_.temporal_tolerance;
  options.tie_mm2 = solve_options_.tie_mm2;
  options.noise2 = seq->sel_sigma2;
  std::vector<std::vector<char>> changed;
  seq->report.bundles_smoothed = hmc::SmoothAnswersInTime(
      data_, neighbours, good, options, &frames, &changed);
  for (size_t i = 0; i < good.size(); ++i) {
    Work& wk = seq->work[good[i]];
    FrameSolve& fs = seq->result.frames[good[i]];
    for (int k = 0; k < K; ++k) {
      if (!changed[i][k]) continue;
      BundleSolve& b = fs.bundles[k];
      b.weights = std::move(weights[i][k]);
      b.global_share = 0.0;
      b.simplex = -1;
      b.corner_shapes.clear();
      wk.use_global[k] = 0;
    }
  }
}

void RobustSolver::SmoothDetailInTime(Sequence* seq) const {
  if (options_.detail_window <= 1 || seq->good.size() < 2) return;
  const int K = data_.num_bundles;
  const std::vector<int>& good = seq->good;
  std::vector<std::vector<std::vector<std::pair<int, double>>>> answers(good.size()),
      detail(good.size());
  std::vector<std::vector<char>> changed(good.size());
  std::vector<DetailFrame> frames(good.size());
  std::vector<int> numbers;
  for (size_t i = 0; i < good.size(); ++i) {
    const Work& wk = seq->work[good[i]];
    const FrameSolve& fs = seq->result.frames[good[i]];
    answers[i].resize(K);
    for (int k = 0; k < K; ++k) {
      if (!wk.use_global[k]) answers[i][k] = fs.bundles[k].weights;
    }
    frames[i] = {&wk.global_nonzero, &answers[i], &wk.use_global, &wk.observed, &detail[i],
                 &changed[i]};
    numbers.push_back(fs.frame);
  }
  seq->report.details_smoothed =
      hmc::SmoothDetailInTime(numbers, options_.detail_window, &frames);
  // The frame's global answer plus the averaged detail (FrameSolve::Weights).
  for (size_t i = 0; i < good.size(); ++i) {
    Work& wk = seq->work[good[i]];
    FrameSolve& fs = seq->result.frames[good[i]];
    fs.global_weights = wk.global_nonzero;
    for (int k = 0; k < K; ++k) {
      if (!changed[i][k]) continue;
      BundleSolve& b = fs.bundles[k];
      b.weights = std::move(detail[i][k]);
      b.global_share = 1.0;
      b.simplex = -1;
      b.corner_shapes = {};
      wk.use_global[k] = 0;
    }
  }
}

}  // namespace hmc
