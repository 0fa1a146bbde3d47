#include "stabilization/stabilize.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <set>

#include <Eigen/Cholesky>
#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "core/error.h"
#include "core/file_util.h"
#include "core/parallel.h"
#include "stabilization/head_fit.h"
#include "stabilization/pose_trajectory.h"
#include "stabilization/rigid_fit.h"

namespace hmc {

void StabilizeOptions::Register(OptionFields* fields) {
  day.Register(fields);
  fields->Add("weighting", &weighting, "motion | tags | both (docs/stabilization.md)")
      .OneOf({"motion", "tags", "both"});
  fields->Add("noise_mm", &noise_mm, "sigma: bundle noise assumed by the motion weights (mm)")
      .Above(0).AtMost(10);
  fields->Add("loss", &loss, "robust loss of the reweighting: none | huber | cauchy")
      .OneOf({"none", "huber", "cauchy"});
  fields->Add("loss_scale_mm", &loss_scale_mm, "residual scale of the robust loss (mm)")
      .Above(0).AtMost(100);
  fields->Add("expression", &expression, "fit global shape weights jointly with the pose");
  fields->Add("shot_weights", &shot_weights,
              "second pass with weights from the first pass's per-marker residuals");
  fields->Add("expression_ridge", &expression_ridge,
              "ridge on the shape weights (mm^2 per unit weight^2)")
      .Above(0).AtMost(1e6);
  fields->Add("max_iterations", &max_iterations, "reweighting rounds per frame at most")
      .In(1, 10000);
  fields->Add("tolerance_mm", &tolerance_mm,
              "converged: a round of reweighting moves no marker further (mm)")
      .Above(0).AtMost(1);
  fields->Add("min_markers", &min_markers, "fewer usable markers: the frame is interpolated")
      .In(3, 10000);
  fields->Add("min_weight", &min_weight, "prior weight (of the largest) a usable marker needs")
      .In(0, 1);
  fields->Add("bad_track_mm", &bad_track_mm,
              "a trusted marker (prior weight >= 0.5) whose median residual exceeds this is "
              "reported (mm)")
      .Above(0);
  fields->Add("temporal_prior", &temporal_prior,
              "poses of frames the dataset explains less well informed by their neighbours");
  fields->Add("smooth_frames", &smooth_frames,
              "centred moving-average window over poses (frames; 0 or 1 = off)")
      .In(0, 1000);
  fields->Add("threads", &threads, "worker threads (0 = all cores)").AtLeast(0);
}

bool StabilizeOptions::Check() const {
  CHECK_OPTION_LIMITS();
  RobustLoss parsed;
  CHECK_OPTION(ParseRobustLoss(loss, &parsed));
  return true;
}

std::string StabilizeOutput::BriefReport() const {
  return fmt::format(
      "{} frames ({} fitted, {} interpolated{}), mean weighted residual {:.3f} mm, {} bad "
      "track(s){}, {:.0f} frames/s",
      frames.size(), num_ok, num_interpolated,
      num_not_converged > 0 ? fmt::format(", {} not converged", num_not_converged) : "",
      mean_rms_mm, bad_tracks.size(),
      unknown_markers.empty() ? ""
                              : fmt::format(", {} unknown marker(s) ignored",
                                            unknown_markers.size()),
      seconds > 0 ? frames.size() / seconds : 0.0);
}

Eigen::VectorXd StabilizationWeights(const MarkerModel& model,
                                     const StabilizeOptions& options) {
  const int K = model.num_markers;
  Eigen::VectorXd w(K);
  for (int k = 0; k < K; ++k) {
    const double m = model.motion_rms[k];
    const double motion = 1.0 / (options.noise_mm * options.noise_mm + m * m);
    if (options.weighting == "tags") {
      w[k] = model.stable[k] ? 1.0 : 0.0;
    } else if (options.weighting == "both") {
      w[k] = model.stable[k] ? motion : 0.0;
    } else {
      w[k] = motion;
    }
  }
  const double top = K > 0 ? w.maxCoeff() : 0.0;
  if (top > 0) w /= top;
  return w;
}

namespace {

// The per-frame fit (stabilization/head_fit.h) with the pass's prior
// weights.
class FrameStabilizer {
 public:
  FrameStabilizer(const MarkerModel& model, const StabilizeOptions& options)
      : model_(model), options_(options), w0_(StabilizationWeights(model, options)) {
    ParseRobustLoss(options.loss, &fit_options_.loss);
    fit_options_.loss_scale_mm = options.loss_scale_mm;
    fit_options_.ridge = options.expression_ridge;
    fit_options_.max_iterations = options.max_iterations;
    fit_options_.tolerance_mm = options.tolerance_mm;
  }

  const Eigen::VectorXd& prior_weights() const { return w0_; }
  void set_prior_weights(const Eigen::VectorXd& w0) { w0_ = w0; }

  // `previous`: this frame's fit of an earlier pass (or null), where the
  // fit starts.
  StabilizedFrame Fit(const BundleFrame& in, const StabilizedFrame* previous) const {
    StabilizedFrame out;
    out.frame = in.frame;
    std::vector<int> ks;
    std::vector<Vec3> points;
    for (const auto& [name, p] : in.bundles) {
      const int k = model_.Find(name);
      if (k < 0) continue;
      ks.push_back(k);
      points.push_back(p);
    }
    const int n = static_cast<int>(ks.size());
    const bool expression = options_.expression && model_.num_shapes > 0;
    Eigen::Matrix3Xd a(3, n), q(3, n);
    Eigen::MatrixXd b(3 * n, expression ? model_.num_shapes : 0);
    Eigen::VectorXd w0(n);
    for (int i = 0; i < n; ++i) {
      a.col(i) = points[i];
      q.col(i) = model_.neutral.row(ks[i]).transpose();
      if (expression) b.middleRows<3>(3 * i) = model_.displacement.middleRows<3>(3 * ks[i]);
      w0[i] = w0_[ks[i]];
      out.markers_used += w0[i] >= options_.min_weight && w0[i] > 0;
    }
    if (out.markers_used < options_.min_markers) {
      out.reason = fmt::format("{} usable markers (min_markers {})", out.markers_used,
                               options_.min_markers);
      return out;
    }
    // Started from the earlier pass's answer, or the rigid fit to the
    // neutral.
    HeadFitResult fit;
    if (previous != nullptr && previous->ok) {
      Eigen::VectorXd residuals(n);
      for (int i = 0; i < n; ++i) residuals[i] = previous->residuals[i].residual_mm;
      fit = FitHeadAndExpression(a, q, b, w0, previous->head_from_helmet, fit_options_,
                                 residuals);
    } else if (const RigidFit start = WeightedRigidFit(a, q, w0); start.ok) {
      fit = FitHeadAndExpression(a, q, b, w0, start.target_from_source, fit_options_);
    }
    if (!fit.ok) {
      out.reason = "usable markers are collinear";
      return out;
    }
    out.ok = true;
    out.head_from_helmet = fit.head_from_helmet;
    out.iterations = fit.iterations;
    out.converged = fit.converged;
    out.last_step_mm = fit.last_step_mm;
    out.information = fit.information;
    double sum_w = 0, sum_wr2 = 0;
    for (int i = 0; i < n; ++i) {
      // Every present marker's residual, also those of zero prior weight.
      Vec3 r = fit.head_from_helmet * a.col(i) - q.col(i);
      if (expression) r -= b.middleRows<3>(3 * i) * fit.shape_weights;
      const double norm = r.norm();
      out.residuals.push_back({ks[i], norm, fit.weights[i]});
      sum_w += fit.weights[i];
      sum_wr2 += fit.weights[i] * norm * norm;
    }
    out.rms_mm = sum_w > 0 ? std::sqrt(sum_wr2 / sum_w) : 0.0;
    return out;
  }

 private:
  const MarkerModel& model_;
  const StabilizeOptions& options_;
  Eigen::VectorXd w0_;
  HeadFitOptions fit_options_;
};

Eigen::Quaterniond Rotation(const Rigid3& t) { return Eigen::Quaterniond(t.linear()); }

Rigid3 Blend(const Rigid3& a, const Rigid3& b, double s) {
  Rigid3 out = Rigid3::Identity();
  out.linear() = Rotation(a).slerp(s, Rotation(b)).toRotationMatrix();
  out.translation() = (1 - s) * a.translation() + s * b.translation();
  return out;
}

// Centred moving average over `window` frames (rotation: the normalised sum
// of quaternions on the hemisphere of the centre's, which is the chordal L2
// mean; Hartley et al. 2013, "Rotation averaging").
void SmoothPoses(int window, std::vector<StabilizedFrame>* frames) {
  if (window <= 1) return;
  const int n = static_cast<int>(frames->size());
  const int half = window / 2;
  std::vector<Rigid3> smoothed(n);
  for (int i = 0; i < n; ++i) {
    const Eigen::Quaterniond centre = Rotation((*frames)[i].head_from_helmet);
    Eigen::Vector4d sum = Eigen::Vector4d::Zero();
    Vec3 translation = Vec3::Zero();
    int count = 0;
    for (int j = std::max(0, i - half); j <= std::min(n - 1, i + half); ++j) {
      Eigen::Quaterniond q = Rotation((*frames)[j].head_from_helmet);
      if (q.dot(centre) < 0) q.coeffs() *= -1;
      sum += q.coeffs();
      translation += (*frames)[j].head_from_helmet.translation();
      ++count;
    }
    smoothed[i] = Rigid3::Identity();
    smoothed[i].linear() = Eigen::Quaterniond(sum.normalized()).toRotationMatrix();
    smoothed[i].translation() = translation / count;
  }
  for (int i = 0; i < n; ++i) (*frames)[i].head_from_helmet = smoothed[i];
}

double Median(std::vector<double> values) {
  if (values.empty()) return 0;
  const size_t mid = values.size() / 2;
  std::nth_element(values.begin(), values.begin() + mid, values.end());
  return values[mid];
}

// The second pass's prior weights (shot_weights): each marker's inverse
// median squared residual v_k over the first pass's fitted frames,
// w_k = 1 / (v_k + v_floor), largest 1. v_floor is the lower quartile of
// v_k over the markers the first pass trusted (prior weight >= 0.5): no
// marker is trusted more than the better quarter of those, so on noise-free
// data a few markers whose residuals happen to vanish (they sit where the
// first pass's small pose error does not move them) do not take over the
// fit. Markers never fitted, or with a zero first weight, get 0.
Eigen::VectorXd ShotWeights(const MarkerModel& model, const std::vector<StabilizedFrame>& frames,
                            const Eigen::VectorXd& first) {
  std::vector<std::vector<double>> squared(model.num_markers);
  for (const StabilizedFrame& frame : frames) {
    if (!frame.ok) continue;
    for (const MarkerResidual& r : frame.residuals) {
      squared[r.marker].push_back(r.residual_mm * r.residual_mm);
    }
  }
  Eigen::VectorXd v = Eigen::VectorXd::Constant(model.num_markers, -1.0);
  std::vector<double> trusted;
  for (int k = 0; k < model.num_markers; ++k) {
    if (squared[k].empty() || first[k] <= 0) continue;
    v[k] = Median(squared[k]);
    if (first[k] >= 0.5) trusted.push_back(v[k]);
  }
  double floor = 1e-12;
  if (!trusted.empty()) {
    const size_t quarter = trusted.size() / 2;
    std::nth_element(trusted.begin(), trusted.begin() + quarter, trusted.end());
    floor = std::max(floor, trusted[quarter]);
  }
  Eigen::VectorXd w = Eigen::VectorXd::Zero(model.num_markers);
  for (int k = 0; k < model.num_markers; ++k) {
    if (v[k] >= 0) w[k] = 1.0 / (v[k] + floor);
  }
  if (w.maxCoeff() > 0) w /= w.maxCoeff();
  return w;
}

// The temporal prior (stabilization/pose_trajectory.h) over the fitted
// frames: sigma_f^2 the frame's weighted mean squared residual per
// coordinate, floored at tolerance^2 (a residual below the fit's
// convergence tolerance says nothing); rotations are about the neutral
// markers' centroid, scaled by their RMS distance from it.
void ApplyTemporalPrior(const MarkerModel& model, double tolerance_mm,
                        std::vector<StabilizedFrame>* frames) {
  std::vector<PoseMeasurement> measurements;
  for (const StabilizedFrame& frame : *frames) {
    PoseMeasurement m;
    m.frame = frame.frame;
    m.pose = frame.head_from_helmet;
    m.ok = frame.ok;
    m.information = frame.information;
    double sum_w = 0, sum_wr2 = 0;
    for (const MarkerResidual& r : frame.residuals) {
      sum_w += r.weight;
      sum_wr2 += r.weight * r.residual_mm * r.residual_mm;
    }
    m.variance_mm2 =
        std::max(tolerance_mm * tolerance_mm, sum_w > 0 ? sum_wr2 / (3 * sum_w) : 0.0);
    measurements.push_back(m);
  }
  const Vec3 center = model.neutral.colwise().mean().transpose();
  const double lever =
      std::sqrt((model.neutral.rowwise() - center.transpose()).rowwise().squaredNorm().mean());
  const std::vector<Rigid3> smoothed =
      SmoothPoseTrajectory(measurements, tolerance_mm, center, lever);
  for (size_t f = 0; f < frames->size(); ++f) {
    StabilizedFrame& frame = (*frames)[f];
    const Rigid3 move = smoothed[f] * frame.head_from_helmet.inverse();
    frame.prior_move_mm = 0;
    for (Eigen::Index k = 0; k < model.neutral.rows(); ++k) {
      const Vec3 q = model.neutral.row(k).transpose();
      frame.prior_move_mm = std::max(frame.prior_move_mm, (move * q - q).norm());
    }
    frame.head_from_helmet = smoothed[f];
  }
}

}  // namespace

void InterpolateFailedPoses(std::vector<StabilizedFrame>* frames) {
  const int n = static_cast<int>(frames->size());
  std::vector<int> good;
  for (int i = 0; i < n; ++i) {
    if ((*frames)[i].ok) good.push_back(i);
  }
  if (good.empty()) return;  // identity stays
  size_t next = 0;           // first good index >= i
  for (int i = 0; i < n; ++i) {
    while (next < good.size() && good[next] < i) ++next;
    StabilizedFrame& frame = (*frames)[i];
    if (frame.ok) continue;
    if (next == 0) {
      frame.head_from_helmet = (*frames)[good.front()].head_from_helmet;
    } else if (next == good.size()) {
      frame.head_from_helmet = (*frames)[good.back()].head_from_helmet;
    } else {
      const StabilizedFrame& before = (*frames)[good[next - 1]];
      const StabilizedFrame& after = (*frames)[good[next]];
      const double s = static_cast<double>(frame.frame - before.frame) /
                       std::max(1, after.frame - before.frame);
      frame.head_from_helmet = Blend(before.head_from_helmet, after.head_from_helmet, s);
    }
  }
}

StabilizeOutput RunStabilize(const MarkerModel& model,
                             const std::vector<BundleFrame>& bundles_helmet,
                             const StabilizeOptions& options) {
  if (!options.Check()) {
    throw InputError("invalid stabilize options (see the message above)");
  }
  const auto start = std::chrono::steady_clock::now();
  ThreadLimit thread_limit(options.threads);
  FrameStabilizer stabilizer(model, options);
  // The dataset's prior weights: which markers should follow the head.
  const Eigen::VectorXd trusted = stabilizer.prior_weights();
  const int num_frames = static_cast<int>(bundles_helmet.size());
  StabilizeOutput out;
  out.frames.resize(num_frames);
  ParallelFor(0, num_frames, [&](int64_t f) {
    out.frames[f] = stabilizer.Fit(bundles_helmet[f], nullptr);
  }, 8);
  if (options.shot_weights) {
    stabilizer.set_prior_weights(ShotWeights(model, out.frames, stabilizer.prior_weights()));
    ParallelFor(0, num_frames, [&](int64_t f) {
      out.frames[f] = stabilizer.Fit(bundles_helmet[f], &out.frames[f]);
    }, 8);
  }
  InterpolateFailedPoses(&out.frames);
  if (options.temporal_prior) ApplyTemporalPrior(model, options.tolerance_mm, &out.frames);
  SmoothPoses(options.smooth_frames, &out.frames);

  std::set<std::string> unknown;
  out.bundles.resize(num_frames);
  double sum_rms = 0;
  std::vector<std::vector<double>> residuals(model.num_markers);
  for (int f = 0; f < num_frames; ++f) {
    StabilizedFrame& frame = out.frames[f];
    out.bundles[f].frame = frame.frame;
    for (const auto& [name, p] : bundles_helmet[f].bundles) {
      out.bundles[f].bundles[name] = frame.head_from_helmet * p;
      if (model.Find(name) < 0) unknown.insert(name);
    }
    if (!frame.ok) {
      ++out.num_interpolated;
      // Residuals against the interpolated pose, with no weight.
      for (const auto& [name, p] : bundles_helmet[f].bundles) {
        const int k = model.Find(name);
        if (k < 0) continue;
        const Vec3 r = frame.head_from_helmet * p - model.neutral.row(k).transpose();
        frame.residuals.push_back({k, r.norm(), 0.0});
      }
      continue;
    }
    ++out.num_ok;
    out.num_not_converged += !frame.converged;
    out.prior_move_max_mm = std::max(out.prior_move_max_mm, frame.prior_move_mm);
    sum_rms += frame.rms_mm;
    for (const MarkerResidual& r : frame.residuals) {
      residuals[r.marker].push_back(r.residual_mm);
    }
  }
  out.mean_rms_mm = out.num_ok > 0 ? sum_rms / out.num_ok : 0.0;
  out.unknown_markers.assign(unknown.begin(), unknown.end());
  for (int k = 0; k < model.num_markers; ++k) {
    if (trusted[k] < 0.5 || residuals[k].empty()) continue;
    const double median = Median(residuals[k]);
    if (median > options.bad_track_mm) out.bad_tracks.push_back({model.names[k], median});
  }
  for (const BadTrack& bad : out.bad_tracks) {
    spdlog::warn("stabilize: marker {} looks like a bad track (median residual {:.2f} mm)",
                 bad.marker, bad.median_residual_mm);
  }
  if (out.num_not_converged > 0) {
    std::string first;
    for (const StabilizedFrame& frame : out.frames) {
      if (frame.ok && !frame.converged) {
        first = fmt::format("frame {}: last step {:.2g} mm", frame.frame, frame.last_step_mm);
        break;
      }
    }
    spdlog::warn("stabilize: {} frame(s) did not converge in {} steps (first: {}); their "
                 "poses are the last step's",
                 out.num_not_converged, options.max_iterations, first);
  }
  if (!out.unknown_markers.empty()) {
    spdlog::warn("stabilize: {} marker name(s) not in the actor ignored (first: {})",
                 out.unknown_markers.size(), out.unknown_markers.front());
  }
  out.seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

void WriteStabilizeOutput(const StabilizeOutput& output,
                          const MarkerModel& model,
                          const StabilizeOptions& options,
                          const std::filesystem::path& dir) {
  EnsureDirectory(dir);
  std::vector<PoseFrame> poses;
  for (const StabilizedFrame& frame : output.frames) {
    poses.push_back({frame.frame, frame.head_from_helmet});
  }
  WritePosesCsv(dir / "head_from_helmet.csv", poses);
  WriteBundlesCsv(dir / "bundles.csv", output.bundles);
  std::string csv = "frame,marker,residual_mm,weight\n";
  for (const StabilizedFrame& frame : output.frames) {
    for (const MarkerResidual& r : frame.residuals) {
      csv += fmt::format("{},{},{:.6g},{:.6g}\n", frame.frame, model.names[r.marker],
                         r.residual_mm, r.weight);
    }
  }
  WriteFileAtomic(dir / "residuals.csv", csv);
  OptionFields used;
  StabilizeOptions copy = options;
  copy.Register(&used);
  WriteOptionsUsed(used, dir / "options_used.yaml", "stabilize");

  nlohmann::json summary;
  summary["stage"] = "stabilize";
  summary["frames"] = output.frames.size();
  summary["fitted"] = output.num_ok;
  summary["interpolated"] = output.num_interpolated;
  summary["mean_residual_mm"] = output.mean_rms_mm;
  summary["seconds"] = output.seconds;
  nlohmann::json interpolated = nlohmann::json::array();
  for (const StabilizedFrame& frame : output.frames) {
    if (!frame.ok) interpolated.push_back({{"frame", frame.frame}, {"reason", frame.reason}});
  }
  summary["interpolated_frames"] = interpolated;
  // Per fitted frame: Gauss-Newton steps and the last step (docs/formats.md).
  nlohmann::json fits = nlohmann::json::array();
  for (const StabilizedFrame& frame : output.frames) {
    if (!frame.ok) continue;
    fits.push_back({{"frame", frame.frame},
                    {"iterations", frame.iterations},
                    {"last_step_mm", frame.last_step_mm},
                    {"converged", frame.converged},
                    {"prior_move_mm", frame.prior_move_mm}});
  }
  summary["not_converged"] = output.num_not_converged;
  summary["prior_move_max_mm"] = output.prior_move_max_mm;
  summary["fits"] = fits;
  nlohmann::json bad = nlohmann::json::array();
  for (const BadTrack& b : output.bad_tracks) {
    bad.push_back({{"marker", b.marker}, {"median_residual_mm", b.median_residual_mm}});
  }
  summary["bad_tracks"] = bad;
  summary["unknown_markers"] = output.unknown_markers;
  summary["report"] = output.BriefReport();
  WriteFileAtomic(dir / "summary.json", summary.dump(2) + "\n");
}

}  // namespace hmc
