// The robust solve's options, report and the sequence of its steps
// (blending/robust_solver.h numbers them; docs/method.md "The robust
// default" names the file of each step).
#include "blending/robust_solver.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <cmath>
#include <string>
#include <utility>

#include "blending/correction_smoothing.h"
#include "blending/robust_solver_state.h"
#include "core/error.h"

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
              "noise variances per bundle")
      .AtLeast(0);
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
              "(step 3b, temporal coherence; <= 1: off)")
      .In(0, 61);
  fields->Add("temporal_tolerance", &temporal_tolerance,
              "the moving average replaces a bundle's answer where its "
              "neighbourhood cost exceeds the answer's by at most this many "
              "noise variances per bundle")
      .AtLeast(0);
  fields->Add("take", &take,
              "whether the frames are a take, a continuous recording (steps "
              "3b and 3c run only on one): auto (the markers' lag-1 "
              "correlation is at least 0.5), yes, no")
      .OneOf({"auto", "yes", "no"});
  fields->Add("correction_window", &correction_window,
              "step 5 on a take: frames of the centred moving average of "
              "the residuals the correction is fitted to (<= 1: off)")
      .In(0, 61);
  fields->Add("detail_window", &detail_window,
              "step 3c on a take: frames of the centred moving average of "
              "each bundle's local detail, its answer less the global one "
              "(<= 1: off)")
      .In(0, 61);
  fields->Add("global_shapes", &global_shapes,
              "the global fit is over at most this many dataset shapes, in "
              "the dataset's order those that add a direction at the "
              "bundles, so that its cost does not grow with the dataset "
              "(0: every shape)")
      .AtLeast(0);
  fields->Add("interpolate", &interpolate,
              "after the correction (part of it: off with correct), "
              "interpolate what is left at each bundle beyond the noise's "
              "universal threshold, with the natural-neighbour weights");
  fields->SetGroup("");
}

bool RobustOptions::Check() const {
  CHECK_OPTION_LIMITS();
  return true;
}

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

std::string RobustReport::BriefReport(bool interpolate,
                                      int good_frames) const {
  return fmt::format(
      "marker noise {:.3f} mm ({}; {:.3f} mm for the choice, {:.3g} "
      "mm for the shape prior), global fit over {} shapes, ridge per shape "
      "{:.3g} (median; smallest {:.3g}), correction {}, {}; {} bundles took the local lgi "
      "choice, {} the global fit, {} the temporal average; {} (lag-1 "
      "correlation {:.2f}){}",
      noise_mm, noise_estimated ? "estimated" : "given",
      selection_noise_mm, prior_noise_mm, global_shapes, ridge,
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
              {"global_shapes", static_cast<double>(global_shapes)},
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

SolveResult RobustSolver::SolveSequence(
    const std::vector<BundleFrame>& frames, const std::vector<JawPose>& jaw,
    const std::vector<std::string>& frame_errors, RobustReport* report_out,
    const MeshSink* sink) {
  HMC_CHECK(jaw.empty() || jaw.size() == frames.size());
  HMC_CHECK(frame_errors.empty() || frame_errors.size() == frames.size());
  Sequence seq(smoothers_);
  seq.report.global_shapes = global_.num_shapes();
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
  BlendFrames(&seq, sink);  // steps 4-6
  const int good_frames = static_cast<int>(seq.good.size());
  spdlog::info("robust: {}",
               seq.report.BriefReport(options_.interpolate, good_frames));
  seq.result.report =
      seq.report.ToMethodReport(options_.interpolate, good_frames);
  if (report_out) *report_out = std::move(seq.report);
  return std::move(seq.result);
}

}  // namespace hmc
