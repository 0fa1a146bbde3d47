#include "blending/robust_solver.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <memory>
#include <tuple>
#include <utility>

#include <Eigen/Eigenvalues>

#include "blending/correction_smoothing.h"
#include "blending/shape_prior.h"
#include "blending/temporal_coherence.h"
#include "core/error.h"
#include "core/jaw.h"
#include "core/logging.h"
#include "core/parallel.h"

namespace hmc {

void RobustOptions::Register(OptionFields* fields) {
  fields->SetGroup("robust");
  fields->Add("noise_mm", &noise_mm,
              "marker noise, std per coordinate (mm); negative: estimated "
              "from the data");
  fields->Add("local", &local,
              "use local geometric indexing where it explains a bundle's "
              "neighbourhood better than the global fit (false: global fit "
              "and correction only)");
  fields->Add("margin", &margin,
              "lgi must beat the global fit's neighbourhood cost by this many "
              "noise variances per bundle");
  fields->Add("ridge", &ridge,
              "one ridge for every shape of the global fit (mm^2 per unit of "
              "weight^2); negative: one per shape, from the sequence's frames "
              "and the marker noise (empirical Bayes)");
  fields->Add("correct", &correct,
              "fit the remaining residual with a Gaussian-kernel smoother");
  fields->Add("smoothing", &smoothing,
              "the correction's smoothing lambda (kernel diagonal = 1); 0: "
              "chosen per sequence by C_p");
  fields->Add("temporal_window", &temporal_window,
              "frames of the centred moving average of each bundle's answer "
              "(step 3b, temporal coherence; <= 1: off)");
  fields->Add("temporal_tolerance", &temporal_tolerance,
              "the moving average replaces a bundle's answer where its "
              "neighbourhood cost exceeds the answer's by at most this many "
              "noise variances per bundle");
  fields->Add("take", &take,
              "whether the frames are a take, a continuous recording (steps "
              "3b and 3c run only on one): auto (the markers' lag-1 "
              "correlation is at least 0.5), yes, no");
  fields->Add("correction_window", &correction_window,
              "step 5 on a take: frames of the centred moving average of "
              "the residuals the correction is fitted to (<= 1: off)");
  fields->Add("detail_window", &detail_window,
              "step 3c on a take: frames of the centred moving average of "
              "each bundle's local detail, its answer less the global one "
              "(<= 1: off)");
  fields->Add("interpolate", &interpolate,
              "after the correction (part of it: off with correct), "
              "interpolate what is left at each bundle beyond the noise's "
              "universal threshold, with the natural-neighbour weights");
  fields->SetGroup("");
}

bool RobustOptions::Check() const {
  if (!std::isfinite(noise_mm)) {
    spdlog::error("robust options: noise_mm must be finite");
    return false;
  }
  if (!(margin >= 0) || !std::isfinite(margin)) {
    spdlog::error("robust options: margin must be >= 0 and finite");
    return false;
  }
  if (temporal_window < 0 || temporal_window > 61) {
    spdlog::error("robust options: temporal_window must be in [0, 61]");
    return false;
  }
  if (take != "auto" && take != "yes" && take != "no") {
    spdlog::error("robust options: take must be auto, yes or no (not '{}')", take);
    return false;
  }
  if (correction_window < 0 || correction_window > 61) {
    spdlog::error("robust options: correction_window must be in [0, 61]");
    return false;
  }
  if (detail_window < 0 || detail_window > 61) {
    spdlog::error("robust options: detail_window must be in [0, 61]");
    return false;
  }
  if (!(temporal_tolerance >= 0) || !std::isfinite(temporal_tolerance)) {
    spdlog::error("robust options: temporal_tolerance must be >= 0 and finite");
    return false;
  }
  if (!std::isfinite(ridge)) {
    spdlog::error("robust options: ridge must be finite");
    return false;
  }
  return true;
}

// One frame's state between the passes.
struct RobustSolver::Work {
  bool ok = false;
  Eigen::VectorXd global;                  // N weights of the global fit
  std::vector<std::pair<int, double>> global_nonzero;  // derived: SetGlobal
  std::vector<Vec3> disp;                  // K observed displacements d_k
  std::vector<char> observed;              // K
  std::vector<char> use_global;            // K
  std::vector<Vec3> residual;              // K: the blend's, at the bundles
  Eigen::MatrixXd alpha;     // K x 3: the kernel's coefficients (empty: none)
  std::vector<Vec3> offset;  // K: interpolated at the bundles (empty: none)

  void SetGlobal(Eigen::VectorXd w) {
    global = std::move(w);
    global_nonzero.clear();
    for (int n = 0; n < global.size(); ++n) {
      if (global[n] != 0) global_nonzero.emplace_back(n, global[n]);
    }
  }
};

// The state of one sequence solve, handed from step to step.
struct RobustSolver::Sequence {
  explicit Sequence(const std::vector<KernelSmoother>& smoothers)
      : bases(smoothers) {}
  SolveResult result;
  std::vector<Work> work;  // per frame
  std::vector<int> good;   // frames with both fits, in order
  std::vector<const std::vector<char>*> good_observed;  // their observed sets
  CorrectionBases bases;
  // Per good frame, K: the global fit's residuals at the bundles and their
  // leave-one-out counterparts (step 2b).
  std::vector<std::vector<Vec3>> global_residual, global_loo;
  double sigma = 0.0;       // the marker noise (mm)
  double sel_sigma2 = 0.0;  // the noise variance step 3 allows (mm^2)
  int width_index = -1;     // the correction's width (-1: none)
  double lambda = 0.0;      // and its smoothing
  RobustReport report;
};

RobustSolver::RobustSolver(const TriMesh& neutral, const ShapeData& data,
                           const LgiSolver& lgi,
                           const NaturalNeighbourWeights& nn,
                           const BlendshapeSolver& global,
                           const SolveOptions& solve_options,
                           const RobustOptions& options)
    : neutral_(neutral),
      data_(data),
      lgi_(lgi),
      nn_(nn),
      global_(global),
      solve_options_(solve_options),
      options_(options) {
  const double spacing = MedianNearestSiteDistance(data.site_neutral, 10.0);
  for (double scale : kCorrectionWidthScales) {
    smoothers_.emplace_back(data.site_neutral, scale * spacing);
  }
}

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

Vec3 RobustSolver::BlendVertex(const Work& work, const FrameSolve& frame,
                               int v) const {
  Vec3 x = neutral_.V.row(v).transpose();
  auto add = [&](const std::vector<std::pair<int, double>>& weights,
                 double scale) {
    for (const auto& [n, w] : weights) {
      const float* bn = data_.Displacement(v, n);
      if (!bn) continue;
      const double c = scale * w;
      x[0] += c * bn[0];
      x[1] += c * bn[1];
      x[2] += c * bn[2];
    }
  };
  double global_share = 0.0;
  for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(
           nn_.weights, v);
       it; ++it) {
    // Its share of the frame's global answer, and its own weights.
    const BundleSolve& b = frame.bundles[it.col()];
    global_share += it.value() * b.global_share;
    add(b.weights, it.value());
  }
  if (global_share > 0) add(work.global_nonzero, global_share);
  return x;
}

std::vector<MatX3d> RobustSolver::BlendBatch(
    const std::vector<const Work*>& work,
    const std::vector<const FrameSolve*>& frames,
    const Eigen::SparseMatrix<double, Eigen::RowMajor>* kernel) const {
  constexpr int B = kBlendBatch;
  const int count = static_cast<int>(work.size());
  HMC_CHECK(count <= B && work.size() == frames.size());
  const int N = data_.num_shapes, K = data_.num_bundles;
  // The kernel's coefficients and the interpolated offsets, per bundle,
  // with the frame innermost: [k][c][frame] (0 in frames without them;
  // empty when no frame of the batch has any).
  auto per_bundle = [&](auto&& get) {
    std::vector<float> out(static_cast<size_t>(K) * 3 * B, 0.0f);
    bool any = false;
    for (int i = 0; i < count; ++i) {
      for (int k = 0; k < K; ++k) {
        for (int c = 0; c < 3; ++c) {
          const double value = get(*work[i], k, c);
          out[(k * 3 + c) * B + i] = static_cast<float>(value);
          any = any || value != 0.0;
        }
      }
    }
    if (!any) out.clear();
    return out;
  };
  const std::vector<float> a =
      kernel ? per_bundle([](const Work& w, int k, int c) {
        return w.alpha.size() > 0 ? w.alpha(k, c) : 0.0;
      })
             : std::vector<float>();
  const std::vector<float> o = per_bundle([](const Work& w, int k, int c) {
    return w.offset.empty() ? 0.0 : w.offset[k][c];
  });
  // The global weights, G[n][frame] (0 in frames without a global fit).
  std::vector<float> G(static_cast<size_t>(N) * B, 0.0f);
  for (int i = 0; i < count; ++i) {
    for (const auto& [n, w] : work[i]->global_nonzero) {
      G[static_cast<size_t>(n) * B + i] = static_cast<float>(w);
    }
  }
  const JawRig* rig = data_.jaw_rig ? &*data_.jaw_rig : nullptr;
  std::vector<Rigid3> jaw(count);
  for (int i = 0; rig && i < count; ++i) jaw[i] = rig->Transform(frames[i]->jaw);
  // Constructed in place: copies of one prototype would memmove 1.2 MB per
  // frame into fresh pages on the calling thread alone.
  std::vector<MatX3d> out;
  out.reserve(count);
  for (int i = 0; i < count; ++i) out.emplace_back(data_.num_vertices, 3);
  ParallelFor(
      0, data_.num_vertices,
      [&](int64_t v) {
        // In single precision, as the displacements are stored (the sums'
        // rounding, ~1e-6 mm, is far below the verification's 1e-3 mm).
        // A vertex no shape moves (44 % of the default actor's) needs no
        // weights.
        float acc[3][B] = {};
        // The shapes that move v and their displacements (the others add 0).
        const int first = data_.vertex_shape_start[v];
        const int last = data_.vertex_shape_start[v + 1];
        const int* moving = data_.vertex_shapes.data();
        const float* d = data_.vertex_shape_displacement.data();
        if (first < last) {
          // The local choices, sum_k lambda_k(v) sum_n u_kn d_n(v), and the
          // natural-neighbour weight (share) of the bundles that took the
          // global fit.
          float share[B] = {};
          for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(
                   nn_.weights, v);
               it; ++it) {
            for (int i = 0; i < count; ++i) {
              // Its share of the frame's global answer, and its own weights.
              const BundleSolve& b = frames[i]->bundles[it.col()];
              if (b.global_share != 0.0) {
                share[i] += static_cast<float>(it.value() * b.global_share);
              }
              for (const auto& [n, u] : b.weights) {
                const float* dn = data_.Displacement(static_cast<int>(v), n);
                if (!dn) continue;
                const float c = static_cast<float>(it.value() * u);
                acc[0][i] += c * dn[0];
                acc[1][i] += c * dn[1];
                acc[2][i] += c * dn[2];
              }
            }
          }
          // share * G over the shapes that move v, frame innermost.
          for (int j = first; j < last; ++j) {
            const int n = moving[j];
            const float d0 = d[3 * j], d1 = d[3 * j + 1], d2 = d[3 * j + 2];
            const float* gn = &G[static_cast<size_t>(n) * B];
            for (int i = 0; i < B; ++i) {
              const float w = share[i] * gn[i];
              acc[0][i] += d0 * w;
              acc[1][i] += d1 * w;
              acc[2][i] += d2 * w;
            }
          }
        }
        // sum_k m(v, k) c_k for per-bundle coefficients c: the kernel's
        // correction and the interpolated offsets.
        auto add_row = [&](const Eigen::SparseMatrix<double, Eigen::RowMajor>& m,
                           const std::vector<float>& coefficients) {
          for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(
                   m, v);
               it; ++it) {
            const float mv = static_cast<float>(it.value());
            const float* ck =
                &coefficients[static_cast<size_t>(it.col()) * 3 * B];
            for (int c = 0; c < 3; ++c) {
              for (int i = 0; i < B; ++i) acc[c][i] += mv * ck[c * B + i];
            }
          }
        };
        if (!a.empty()) add_row(*kernel, a);
        if (!o.empty()) add_row(nn_.weights, o);
        for (int i = 0; i < count; ++i) {
          Vec3 x;
          for (int c = 0; c < 3; ++c) x[c] = neutral_.V(v, c) + acc[c][i];
          if (rig) x = SkinPoint(jaw[i], x, rig->weights[v]);
          out[i].row(v) = x.transpose();
        }
      },
      256);
  return out;
}

std::string RobustReport::BriefReport(bool interpolate,
                                      int good_frames) const {
  return fmt::format(
      "marker noise {:.3f} mm ({}; {:.3f} mm for the choice, {:.3g} "
      "mm for the shape prior), global ridge per shape {:.3g} (median; "
      "smallest {:.3g}), correction {}, {}; {} bundles took the local lgi "
      "choice, {} the global fit, {} the temporal average; {} (lag-1 "
      "correlation {:.2f}){}",
      noise_mm, noise_estimated ? "estimated" : "given",
      selection_noise_mm, prior_noise_mm, ridge,
      ridge_min,
      lambda > 0
          ? fmt::format("width {:.1f} mm, smoothing {:.3g} ({} of {} frames "
                        "left uncorrected)",
                        width_mm, lambda,
                        frames_uncorrected, good_frames)
          : std::string("none"),
      interpolate
          ? fmt::format("{} bundles interpolated beyond {:.3f} mm",
                        bundles_interpolated, threshold_mm)
          : std::string("no interpolation"),
      bundles_local, bundles_global, bundles_smoothed, take ? "a take" : "not a take",
      take_correlation,
      (details_smoothed > 0 ? fmt::format(", {} local details averaged in time", details_smoothed)
                            : std::string()) +
          (correction_noise_kept < 1.0
               ? fmt::format(", the correction fitted to residuals averaged in time ({:.0f} % "
                             "of their noise variance kept)",
                             100 * correction_noise_kept)
               : std::string()));
}

MethodReport RobustReport::ToMethodReport(bool interpolate,
                                          int good_frames) const {
  MethodReport r;
  r.values = {{"noise_mm", noise_mm},
              {"noise_estimated", noise_estimated ? 1.0 : 0.0},
              {"selection_noise_mm", selection_noise_mm},
              {"prior_noise_mm", prior_noise_mm},
              {"ridge_median", ridge},
              {"ridge_min", ridge_min},
              {"correction_width_mm", width_mm},
              {"correction_smoothing", lambda},
              {"frames_uncorrected", static_cast<double>(frames_uncorrected)},
              {"interpolation_threshold_mm", threshold_mm},
              {"bundles_interpolated",
               static_cast<double>(bundles_interpolated)},
              {"bundles_local", static_cast<double>(bundles_local)},
              {"bundles_global", static_cast<double>(bundles_global)},
              {"bundles_smoothed", static_cast<double>(bundles_smoothed)},
              {"take_correlation", take_correlation},
              {"take", take ? 1.0 : 0.0},
              {"details_smoothed", static_cast<double>(details_smoothed)},
              {"correction_noise_kept", correction_noise_kept}};
  r.brief = BriefReport(interpolate, good_frames);
  return r;
}

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
      wk.SetGlobal(std::move(w));
      start = &wk.global;
      wk.ok = true;
      wk.observed.assign(K, 0);
      wk.disp.assign(K, Vec3::Zero());
      for (int k = 0; k < K; ++k) {
        const BundleSolve& b = fs.bundles[k];
        if (b.status != BundleSolve::Status::kInside &&
            b.status != BundleSolve::Status::kProjected) {
          continue;
        }
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
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return std::min(s2, v[v.size() / 2]);
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
            ? Eigen::VectorXd::Constant(data_.num_shapes, options_.ridge)
            : ChooseShapePrior(
                  global_, good_observed, disp, sigma,
                  options_.noise_mm < 0 ? std::sqrt(ChoiceNoiseVariance(*seq)) : -1.0,
                  data_.num_shapes, &report.prior_noise_mm);
    std::vector<double> sorted(ridges.data(), ridges.data() + ridges.size());
    std::sort(sorted.begin(), sorted.end());
    report.shape_ridge.assign(ridges.data(), ridges.data() + ridges.size());
    report.ridge_min = sorted.front();
    report.ridge = sorted[sorted.size() / 2];
    if (sorted.back() > 0) {
      ParallelFor(0, static_cast<int64_t>(good.size()), [&](int64_t i) {
        Work& wk = work[good[i]];
        wk.SetGlobal(global_.FitWeights(wk.observed, disp[i], ridges,
                                        &wk.global));
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

// Steps 4-6, kBlendBatch good frames at a time; bad frames repeat the
// previous good mesh.
void RobustSolver::BlendFrames(Sequence* seq) const {
  const int F = static_cast<int>(seq->work.size()), K = data_.num_bundles;
  std::vector<Work>& work = seq->work;
  SolveResult& result = seq->result;
  const int width_index = seq->width_index;
  const JawRig* rig = data_.jaw_rig ? &*data_.jaw_rig : nullptr;
  Progress progress("robust: blend", F);
  SolveSummary& s = result.summary;
  s.frames = F;
  const auto* kernel =
      width_index >= 0 ? &vertex_kernel_.at(width_index) : nullptr;
  for (int begin = 0; begin < F;) {
    std::vector<const Work*> batch_work;
    std::vector<const FrameSolve*> batch_frames;
    int end = begin;
    for (; end < F && batch_work.size() < kBlendBatch; ++end) {
      const Work& wk = work[end];
      if (!wk.ok) continue;
      batch_work.push_back(&wk);
      batch_frames.push_back(&result.frames[end]);
    }
    std::vector<MatX3d> blended = BlendBatch(batch_work, batch_frames, kernel);
    for (int f = begin, i = 0; f < end; ++f) {
      FrameSolve& fs = result.frames[f];
      Work& wk = work[f];
      if (wk.ok) {
        result.meshes[f] = std::move(blended[i++]);
        for (int k = 0; k < K; ++k) {
          BundleSolve& b = fs.bundles[k];
          if (wk.observed[k]) {
            b.residual = (EvaluateSurfacePoint(data_.sites[k], neutral_.F,
                                               result.meshes[f]) -
                          b.observed)
                             .norm();
          }
        }
      }
      // The frame's working state is done with: released as the meshes
      // come, so a long shot holds its meshes and records, not both.
      wk = Work();
      s.Count(fs);
      progress.Advance();
    }
    begin = end;
  }
  FillBadMeshes(neutral_, rig, &result);
}

SolveResult RobustSolver::SolveSequence(
    const std::vector<BundleFrame>& frames, const std::vector<JawPose>& jaw,
    const std::vector<std::string>& frame_errors, RobustReport* report_out) {
  HMC_CHECK(jaw.empty() || jaw.size() == frames.size());
  HMC_CHECK(frame_errors.empty() || frame_errors.size() == frames.size());
  Sequence seq(smoothers_);
  SolveLgiAndGlobal(frames, jaw, frame_errors, &seq);  // step 1
  EstimateNoise(&seq);                                 // step 2
  FitShapePrior(&seq);                                 // step 2b
  ChooseLocalOrGlobal(&seq);                           // step 3
  // The global fit's residuals served steps 2-3 only.
  seq.global_residual = {};
  seq.global_loo = {};
  if (IsTake(&seq)) {
    SmoothAnswersInTime(&seq);                         // step 3b
    SmoothDetailInTime(&seq);                          // step 3c
  }
  if (options_.correct && !seq.good.empty()) {
    ChooseCorrection(&seq);  // step 5's width and smoothing
    if (options_.interpolate) InterpolateBeyondThreshold(&seq);
  }
  seq.bases.Clear();  // step 5's decompositions, before the meshes come
  seq.report.lambda = seq.lambda;
  BlendFrames(&seq);  // steps 4-6
  const int good_frames = static_cast<int>(seq.good.size());
  spdlog::info("robust: {}",
               seq.report.BriefReport(options_.interpolate, good_frames));
  seq.result.report =
      seq.report.ToMethodReport(options_.interpolate, good_frames);
  if (report_out) *report_out = std::move(seq.report);
  return std::move(seq.result);
}

}  // namespace hmc
