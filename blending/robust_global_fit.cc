// Steps 1 and 2b of the robust solve (blending/robust_solver.h): lgi's
// choices and the bounded global fit per frame, then the global fit again
// with the per-shape ridge of the shape prior (blending/shape_prior.h) and
// its leave-one-out residuals.
#include <algorithm>
#include <cmath>
#include <utility>
#include <vector>

#include "blending/robust_solver.h"
#include "blending/robust_solver_state.h"
#include "blending/shape_prior.h"
#include "core/parallel.h"

namespace hmc {

void RobustSolver::SolveLgiAndGlobal(
    const std::vector<BundleFrame>& frames, const std::vector<JawPose>& jaw,
    const std::vector<std::string>& frame_errors, Sequence* seq) const {
  const int F = static_cast<int>(frames.size()), K = data_.num_bundles;
  SolveResult& result = seq->result;
  std::vector<Work>& work = seq->work;
  work.resize(F);
  // Step 1: lgi's choices, frame by frame (its temporal preference looks at
  // the previous frame) ...
  const FrameSolve* previous = nullptr;
  SolveFrames(
      frames, jaw, frame_errors, K, "robust: lgi choice",
      [&](int f, const JawPose& pose, FrameSolve* out) {
        *out = lgi_.SolveFrame(frames[f], pose, previous);
        if (out->ok) previous = out;
      },
      &result);
  // ... and the global fit, in runs of consecutive frames solved in
  // parallel, each frame warm-started from the one before it in its run.
  // Short runs keep the cores evenly loaded (24 frames in runs of 8 left one
  // core idle for a third of the step); the warm start still pays within 4.
  constexpr int kRun = 4;
  ParallelFor(0, (F + kRun - 1) / kRun, [&](int64_t run) {
    const Eigen::VectorXd* start = nullptr;
    for (int f = static_cast<int>(run) * kRun;
         f < std::min(F, static_cast<int>(run + 1) * kRun); ++f) {
      FrameSolve& fs = result.frames[f];
      if (!fs.ok) continue;
      Work& wk = work[f];
      Eigen::VectorXd w;
      const FrameSolve global =
          global_.SolveFrame(frames[f], fs.jaw, &w, nullptr, start);
      if (!global.ok) {
        fs.ok = false;
        fs.reason = global.reason;
        continue;
      }
      wk.SetGlobal(std::move(w), global_.shapes());
      start = &wk.global;
      wk.ok = true;
      wk.observed.assign(K, 0);
      wk.disp.assign(K, Vec3::Zero());
      for (int k = 0; k < K; ++k) {
        const BundleSolve& b = fs.bundles[k];
        if (!b.Measured()) continue;
        wk.observed[k] = 1;
        wk.disp[k] = UnskinBundle(data_, k, fs.jaw, b.observed) -
                     data_.site_neutral.row(k).transpose();
      }
    }
  });
  LgiSolver::SmoothWeights(solve_options_.smooth_window, &result.frames);
  result.meshes.resize(F);

  for (int f = 0; f < F; ++f) {
    if (work[f].ok) {
      seq->good.push_back(f);
      seq->good_observed.push_back(&work[f].observed);
    }
  }
}

void RobustSolver::FitShapePrior(Sequence* seq) const {
  const int K = data_.num_bundles;
  std::vector<Work>& work = seq->work;
  const std::vector<int>& good = seq->good;
  const double sigma = seq->sigma;
  RobustReport& report = seq->report;
  std::vector<std::vector<Vec3>>& global_residual = seq->global_residual;
  const std::vector<const std::vector<char>*>& good_observed =
      seq->good_observed;
  // Step 2b: the global fit again, with the ridge the noise calls for.
  // Then its residuals as a fit without each bundle would leave them: lgi's
  // cost in step 3 is a prediction (its simplex passes through the bundle
  // and is scored on the neighbours), so the global fit is scored by
  // prediction too, not by residuals it was fitted to.
  std::vector<std::vector<Vec3>>& global_loo = seq->global_loo;
  global_loo.resize(good.size());
  {
    std::vector<Eigen::VectorXd> disp(good.size());
    for (size_t i = 0; i < good.size(); ++i) {
      disp[i] = Eigen::VectorXd::Zero(3 * K);
      for (int k = 0; k < K; ++k) {
        disp[i].segment<3>(3 * k) = work[good[i]].disp[k];
      }
    }
    const Eigen::VectorXd ridges =
        options_.ridge >= 0
            ? Eigen::VectorXd::Constant(global_.num_shapes(), options_.ridge)
            : ChooseShapePrior(
                  global_, good_observed, disp, sigma,
                  options_.noise_mm < 0 ? std::sqrt(ChoiceNoiseVariance(*seq)) : -1.0,
                  global_.num_shapes(), &report.prior_noise_mm);
    std::vector<double> sorted(ridges.data(), ridges.data() + ridges.size());
    std::sort(sorted.begin(), sorted.end());
    report.shape_ridge.assign(ridges.data(), ridges.data() + ridges.size());
    report.ridge_min = sorted.front();
    report.ridge = sorted[sorted.size() / 2];
    if (sorted.back() > 0) {
      ParallelFor(0, static_cast<int64_t>(good.size()), [&](int64_t i) {
        Work& wk = work[good[i]];
        wk.SetGlobal(global_.FitWeights(wk.observed, disp[i], ridges,
                                        &wk.global),
                     global_.shapes());
        for (int k = 0; k < K; ++k) {
          if (wk.observed[k]) {
            global_residual[i][k] =
                wk.disp[k] - global_.SiteDisplacement(k, wk.global);
          }
        }
      }, 1);
    }
    const Eigen::VectorXd fitted_ridges =
        sorted.back() > 0 ? ridges : Eigen::VectorXd::Zero(ridges.size());
    ParallelFor(0, static_cast<int64_t>(good.size()), [&](int64_t i) {
      const Work& wk = work[good[i]];
      global_loo[i] = global_.LeaveOneOutResiduals(
          wk.observed, wk.global, fitted_ridges, global_residual[i]);
    }, 1);
  }
}

}  // namespace hmc
