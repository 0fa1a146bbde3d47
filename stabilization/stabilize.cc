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
#include "stabilization/rigid_fit.h"

namespace hmc {

void StabilizeOptions::Register(OptionFields* fields) {
  fields->Add("weighting", &weighting, "motion | tags | both (docs/stabilization.md)");
  fields->Add("noise_mm", &noise_mm, "sigma: bundle noise assumed by the motion weights (mm)");
  fields->Add("loss", &loss, "robust loss of the reweighting: none | huber | cauchy");
  fields->Add("loss_scale_mm", &loss_scale_mm, "residual scale of the robust loss (mm)");
  fields->Add("irls_iterations", &irls_iterations, "most reweighting steps per fit");
  fields->Add("expression", &expression, "alternate the rigid fit with global shape weights");
  fields->Add("shot_weights", &shot_weights,
              "second pass with weights from the first pass's per-marker residuals");
  fields->Add("expression_iterations", &expression_iterations,
              "rigid / shape-weight alternations (expression)");
  fields->Add("expression_ridge", &expression_ridge,
              "ridge on the shape weights (mm^2 per unit weight^2)");
  fields->Add("min_markers", &min_markers, "fewer usable markers: the frame is interpolated");
  fields->Add("min_weight", &min_weight, "prior weight (of the largest) a usable marker needs");
  fields->Add("bad_track_mm", &bad_track_mm,
              "a trusted marker (prior weight >= 0.5) whose median residual exceeds this is "
              "reported (mm)");
  fields->Add("smooth_frames", &smooth_frames,
              "centred moving-average window over poses (frames; 0 or 1 = off)");
  fields->Add("threads", &threads, "worker threads (0 = all cores)");
}

bool StabilizeOptions::Check() const {
  bool ok = true;
  auto fail = [&](const std::string& message) {
    spdlog::error("stabilize options: {}", message);
    ok = false;
  };
  if (weighting != "motion" && weighting != "tags" && weighting != "both") {
    fail(fmt::format("weighting must be motion, tags or both, got '{}'", weighting));
  }
  RobustLoss parsed;
  if (!ParseRobustLoss(loss, &parsed)) {
    fail(fmt::format("loss must be none, huber or cauchy, got '{}'", loss));
  }
  if (!(noise_mm > 0 && noise_mm <= 10)) fail("noise_mm must be in (0, 10]");
  if (!(loss_scale_mm > 0 && loss_scale_mm <= 100)) fail("loss_scale_mm must be in (0, 100]");
  if (irls_iterations < 0 || irls_iterations > 1000) fail("irls_iterations must be in [0, 1000]");
  if (expression_iterations < 1 || expression_iterations > 100) {
    fail("expression_iterations must be in [1, 100]");
  }
  if (!(expression_ridge > 0 && expression_ridge <= 1e6)) {
    fail("expression_ridge must be in (0, 1e6]");
  }
  if (min_markers < 3 || min_markers > 10000) fail("min_markers must be in [3, 10000]");
  if (!(min_weight >= 0 && min_weight <= 1)) fail("min_weight must be in [0, 1]");
  if (!(bad_track_mm > 0)) fail("bad_track_mm must be positive");
  if (smooth_frames < 0 || smooth_frames > 1000) fail("smooth_frames must be in [0, 1000]");
  return ok;
}

std::string StabilizeOutput::BriefReport() const {
  return fmt::format(
      "{} frames ({} fitted, {} interpolated), mean weighted residual {:.3f} mm, {} bad "
      "track(s){}, {:.0f} frames/s",
      frames.size(), num_ok, num_interpolated, mean_rms_mm, bad_tracks.size(),
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

// Residuals beyond this many loss scales leave the marker out of the next
// shape-weight fit (Cauchy weight below 0.1).
constexpr double kOutlierScales = 3.0;

// The per-frame fit: precomputed prior weights and, for the expression-
// aware fit, the Cholesky factor of B^T B + lambda I over all markers.
class FrameStabilizer {
 public:
  FrameStabilizer(const MarkerModel& model, const StabilizeOptions& options)
      : model_(model), options_(options), w0_(StabilizationWeights(model, options)) {
    ParseRobustLoss(options.loss, &loss_);
    if (options.expression && model.num_shapes > 0) {
      const Eigen::MatrixXd& b = model.displacement;
      normal_ = b.transpose() * b;
      normal_.diagonal().array() += options.expression_ridge;
      full_factor_.compute(normal_);
    }
  }

  const Eigen::VectorXd& prior_weights() const { return w0_; }
  void set_prior_weights(const Eigen::VectorXd& w0) { w0_ = w0; }

  StabilizedFrame Fit(const BundleFrame& in) const {
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
    Eigen::Matrix3Xd a(3, n), q(3, n);
    Eigen::VectorXd w0(n);
    for (int i = 0; i < n; ++i) {
      a.col(i) = points[i];
      q.col(i) = model_.neutral.row(ks[i]).transpose();
      w0[i] = w0_[ks[i]];
      out.markers_used += w0[i] >= options_.min_weight && w0[i] > 0;
    }
    if (out.markers_used < options_.min_markers) {
      out.reason = fmt::format("{} usable markers (min_markers {})", out.markers_used,
                               options_.min_markers);
      return out;
    }
    Eigen::Matrix3Xd target = q;
    Eigen::VectorXd w = w0;
    RigidFit fit = WeightedRigidFit(a, target, w);
    const int outer = options_.expression && model_.num_shapes > 0
                          ? options_.expression_iterations + 1
                          : 1;
    std::vector<char> inlier(n, 1);
    for (int round = 0; round < outer && fit.ok; ++round) {
      if (round > 0) {
        target = q + ExpressionOffsets(ks, inlier, fit.target_from_source * a - q);
      }
      fit = Reweighted(a, target, w0, &w);
      // A marker far off the expression's fit (a bad track) would pull the
      // shape weights: the next shape fit leaves it out. (Before the first
      // shape fit every moving marker is far off the neutral.)
      if (round > 0 && loss_ != RobustLoss::kNone && fit.ok) {
        const Eigen::Matrix3Xd r = fit.target_from_source * a - target;
        for (int i = 0; i < n; ++i) {
          inlier[i] = r.col(i).norm() <= kOutlierScales * options_.loss_scale_mm;
        }
      }
    }
    if (!fit.ok) {
      out.reason = "usable markers are collinear";
      return out;
    }
    out.ok = true;
    out.head_from_helmet = fit.target_from_source;
    const Eigen::Matrix3Xd r = fit.target_from_source * a - target;
    double sum_w = 0, sum_wr2 = 0;
    for (int i = 0; i < n; ++i) {
      const double norm = r.col(i).norm();
      out.residuals.push_back({ks[i], norm, w[i]});
      sum_w += w[i];
      sum_wr2 += w[i] * norm * norm;
    }
    out.rms_mm = sum_w > 0 ? std::sqrt(sum_wr2 / sum_w) : 0.0;
    return out;
  }

 private:
  // IRLS from the prior weights; *w receives the final weights.
  RigidFit Reweighted(const Eigen::Matrix3Xd& a, const Eigen::Matrix3Xd& target,
                      const Eigen::VectorXd& w0, Eigen::VectorXd* w) const {
    *w = w0;
    RigidFit fit = WeightedRigidFit(a, target, *w);
    if (loss_ == RobustLoss::kNone) return fit;
    for (int it = 0; it < options_.irls_iterations && fit.ok; ++it) {
      const Eigen::Matrix3Xd r = fit.target_from_source * a - target;
      for (int i = 0; i < a.cols(); ++i) {
        (*w)[i] = w0[i] * RobustWeight(loss_, r.col(i).norm(), options_.loss_scale_mm);
      }
      const RigidFit next = WeightedRigidFit(a, target, *w);
      if (!next.ok) return next;
      const double change =
          (next.target_from_source.matrix() - fit.target_from_source.matrix()).norm();
      fit = next;
      if (change < 1e-9) break;  // mm and rad: far below any accuracy asked
    }
    return fit;
  }

  // B_k c for the present markers ks, c the ridge fit of the residuals d
  // (3 x n) of the inliers: min_c sum_inliers |d_k - B_k c|^2 + lambda |c|^2.
  Eigen::Matrix3Xd ExpressionOffsets(const std::vector<int>& ks, const std::vector<char>& inlier,
                                     const Eigen::Matrix3Xd& d) const {
    const Eigen::MatrixXd& b = model_.displacement;
    const int n = static_cast<int>(ks.size());
    Eigen::VectorXd rhs = Eigen::VectorXd::Zero(model_.num_shapes);
    std::vector<char> used(model_.num_markers, 0);
    int num_used = 0;
    for (int i = 0; i < n; ++i) {
      if (!inlier[i]) continue;
      rhs.noalias() += b.middleRows<3>(3 * ks[i]).transpose() * d.col(i);
      used[ks[i]] = 1;
      ++num_used;
    }
    Eigen::VectorXd c;
    if (num_used == model_.num_markers) {
      c = full_factor_.solve(rhs);
    } else {
      // Missing or left-out markers: take their terms out of the normal
      // matrix.
      c = NormalWithout(normal_, b, used).llt().solve(rhs);
    }
    Eigen::Matrix3Xd offsets(3, n);
    for (int i = 0; i < n; ++i) offsets.col(i) = b.middleRows<3>(3 * ks[i]) * c;
    return offsets;
  }

  const MarkerModel& model_;
  const StabilizeOptions& options_;
  Eigen::VectorXd w0_;
  RobustLoss loss_ = RobustLoss::kCauchy;
  Eigen::MatrixXd normal_;
  Eigen::LLT<Eigen::MatrixXd> full_factor_;
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
    out.frames[f] = stabilizer.Fit(bundles_helmet[f]);
  }, 8);
  if (options.shot_weights) {
    stabilizer.set_prior_weights(ShotWeights(model, out.frames, stabilizer.prior_weights()));
    ParallelFor(0, num_frames, [&](int64_t f) {
      out.frames[f] = stabilizer.Fit(bundles_helmet[f]);
    }, 8);
  }
  InterpolateFailedPoses(&out.frames);
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
  WriteOptionsUsed(used, dir / "options_used.yaml");

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
