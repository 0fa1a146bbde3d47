#include "stabilization/jaw_fit.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include <Eigen/Cholesky>
#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "core/error.h"
#include "core/file_util.h"
#include "core/parallel.h"
#include "stabilization/jaw_cost.h"

namespace hmc {

void JawOptions::Register(OptionFields* fields) {
  day.Register(fields);
  fields->Add("smoothness", &smoothness,
              "mu: temporal prior on second differences (mm^2 per deg^2, or per mm^2 for "
              "protrude; 0 = off)")
      .In(0, 1e6);
  fields->Add("bound_margin", &bound_margin,
              "bounds: the dataset's jaw range widened by this fraction of it (at least 1 deg "
              "/ 1 mm) on each side")
      .In(0, 10);
  fields->Add("ridge", &ridge, "lambda: ridge on the global shape weights (mm^2 per unit weight^2)")
      .Above(0).AtMost(1e6);
  fields->Add("min_jaw_markers", &min_jaw_markers,
              "fewer jaw markers present: the frame is interpolated")
      .In(2, 10000);
  fields->Add("min_marker_fraction", &min_marker_fraction,
              "a fit on fewer than this fraction of the shot's median jaw-marker count is "
              "not trusted: the frame is interpolated (0 = off)")
      .In(0, 1);
  fields->Add("max_residual_ratio", &max_residual_ratio,
              "> 0: a fit whose jaw-marker residual exceeds this many times the shot's median is "
              "not trusted: the frame is interpolated (0 = off, else at least 1)")
      .In(0, 1e6);
  fields->Add("lip_prefix", &lip_prefix,
              "markers named so (or tagged lower_lip) join the jaw markers");
  fields->Add("max_solver_iterations", &max_solver_iterations,
              "Ceres iterations per frame")
      .In(1, 1000);
  fields->Add("threads", &threads, "worker threads (0 = all cores)").AtLeast(0);
}

bool JawOptions::Check() const {
  CHECK_OPTION_LIMITS();
  CHECK_OPTION(max_residual_ratio == 0 || max_residual_ratio >= 1);
  return true;
}

std::string JawOutput::BriefReport() const {
  return fmt::format(
      "{} frames ({} fitted, {} interpolated), mean jaw-marker residual {:.3f} mm, {:.0f} "
      "frames/s",
      frames.size(), num_ok, num_interpolated, mean_rms_mm,
      seconds > 0 ? frames.size() / seconds : 0.0);
}

std::vector<JawFrame> JawOutput::JawFrames() const {
  std::vector<JawFrame> out;
  for (const JawFit& fit : frames) out.push_back({fit.frame, fit.pose});
  return out;
}

std::vector<int> JawMarkers(const MarkerModel& model, const Actor& actor,
                            const JawOptions& options) {
  std::vector<int> out;
  for (int k = 0; k < model.num_markers; ++k) {
    const Marker& marker = actor.markers[k];
    const bool lip = (!options.lip_prefix.empty() &&
                      marker.name.rfind(options.lip_prefix, 0) == 0) ||
                     marker.HasTag("lower_lip");
    if ((model.jaw[k] || lip) && model.jaw_weight[k] > 0) out.push_back(k);
  }
  return out;
}

namespace {

using Pose = std::array<double, 3>;

class FrameJawFitter {
 public:
  FrameJawFitter(const MarkerModel& model, const std::vector<int>& jaw_markers,
                 const JawOptions& options, const Pose& lower, const Pose& upper)
      : model_(model), options_(options), lower_(lower), upper_(upper),
        in_jaw_(model.num_markers, 0) {
    for (int k : jaw_markers) in_jaw_[k] = 1;
    const Eigen::MatrixXd& b = model.unskinned_displacement;
    normal_ = b.transpose() * b;
    normal_.diagonal().array() += options.ridge;
    full_projection_ = Projection(Eigen::LLT<Eigen::MatrixXd>(normal_), AllMarkers());
  }

  JawFit Fit(const BundleFrame& in) const {
    JawFit out;
    out.frame = in.frame;
    FrameMarkers frame;
    std::vector<std::pair<int, Vec3>> present;
    for (const auto& [name, p] : in.bundles) {
      const int k = model_.Find(name);
      if (k >= 0) present.emplace_back(k, p);
    }
    std::sort(present.begin(), present.end(),
              [](const auto& a, const auto& b) { return a.first < b.first; });
    for (const auto& [k, p] : present) {
      if (in_jaw_[k]) frame.jaw.push_back(static_cast<int>(frame.ks.size()));
      frame.ks.push_back(k);
      frame.points.push_back(p);
    }
    out.jaw_markers = static_cast<int>(frame.jaw.size());
    if (out.jaw_markers < options_.min_jaw_markers) {
      out.reason = fmt::format("{} jaw markers (min_jaw_markers {})", out.jaw_markers,
                               options_.min_jaw_markers);
      return out;
    }
    const Eigen::MatrixXd& projection =
        static_cast<int>(frame.ks.size()) == model_.num_markers
            ? full_projection_
            : Projection(PartialFactor(frame.ks), frame.ks);
    SplitProjection(projection, &frame);
    Pose theta;
    for (int i = 0; i < 3; ++i) theta[i] = std::clamp(0.0, lower_[i], upper_[i]);
    ceres::Problem problem;
    problem.AddResidualBlock(
        new ceres::NumericDiffCostFunction<ProjectedResidual, ceres::CENTRAL, ceres::DYNAMIC, 3>(
            new ProjectedResidual(&model_, &frame), ceres::TAKE_OWNERSHIP, 3 * out.jaw_markers),
        nullptr, theta.data());
    for (int i = 0; i < 3; ++i) {
      problem.SetParameterLowerBound(theta.data(), i, lower_[i]);
      problem.SetParameterUpperBound(theta.data(), i, upper_[i]);
    }
    ceres::Solver::Options solver;
    solver.linear_solver_type = ceres::DENSE_QR;
    solver.max_num_iterations = options_.max_solver_iterations;
    solver.logging_type = ceres::SILENT;
    solver.num_threads = 1;
    solver.function_tolerance = 1e-12;
    solver.gradient_tolerance = 1e-14;
    solver.parameter_tolerance = 1e-10;
    ceres::Solver::Summary summary;
    ceres::Solve(solver, &problem, &summary);
    double cost = 0;
    ceres::CRSMatrix jacobian;
    problem.Evaluate(ceres::Problem::EvaluateOptions(), &cost, nullptr, nullptr, &jacobian);
    Eigen::MatrixXd j = Eigen::MatrixXd::Zero(jacobian.num_rows, 3);
    for (int r = 0; r < jacobian.num_rows; ++r) {
      for (int e = jacobian.rows[r]; e < jacobian.rows[r + 1]; ++e) {
        j(r, jacobian.cols[e]) = jacobian.values[e];
      }
    }
    out.information = j.transpose() * j;
    out.rms_mm = std::sqrt(2 * cost / out.jaw_markers);
    out.pose = JawPose::FromArray(theta);
    out.ok = true;
    return out;
  }

 private:
  // One frame's markers (ascending model index), their bundles, which are
  // jaw markers, and the shape weights' effect on the jaw markers split
  // into what the jaw pose cannot change (markers without jaw weight: their
  // unskinned bundles do not depend on theta) and what it can.
  struct FrameMarkers {
    std::vector<int> ks;
    std::vector<Vec3> points;
    std::vector<int> jaw;        // positions in ks
    std::vector<int> dynamic;    // positions in ks with jaw weight > 0
    Eigen::VectorXd base;        // 3|J|: x0_J + P_static d_static
    Eigen::MatrixXd dynamic_projection;  // 3|J| x 3|dynamic|
  };

  // Variable projection (Golub & Pereyra 1973): the jaw markers' residuals
  // p_k - S_k(T(theta), u_k(c*(theta))) with the shape weights eliminated,
  //   c*(theta) = argmin_c sum_k |S_k^-1(p_k; theta) - x0(s_k) - B*_k c|^2
  //               + lambda |c|^2   (all present markers),
  // so Ceres moves theta and c together (alternating the two steps
  // converges slowly: the shapes and the jaw both move the chin). With the
  // projection P = B*_J (B*^T B* + lambda I)^-1 B*^T precomputed, the jaw
  // markers' unskinned positions are u_J = x0_J + P d(theta).
  struct ProjectedResidual {
    ProjectedResidual(const MarkerModel* model, const FrameMarkers* frame)
        : model(model), frame(frame) {}
    bool operator()(const double* theta, double* residual) const {
      const JawRig& rig = *model->jaw_rig;
      const Rigid3 t = rig.Transform(JawPose::FromArray({theta[0], theta[1], theta[2]}));
      Eigen::VectorXd d(3 * frame->dynamic.size());
      for (size_t i = 0; i < frame->dynamic.size(); ++i) {
        const int at = frame->dynamic[i];
        const int k = frame->ks[at];
        d.segment<3>(3 * i) =
            model->Unskin(k, t, frame->points[at]) - model->neutral.row(k).transpose();
      }
      const Eigen::VectorXd u = frame->base + frame->dynamic_projection * d;
      for (size_t j = 0; j < frame->jaw.size(); ++j) {
        const int k = frame->ks[frame->jaw[j]];
        const Vec3 uj = u.segment<3>(3 * j);
        const JawMarkerCost cost(rig, frame->points[frame->jaw[j]], &uj, model->jaw_weight[k],
                                 model->jaw_moment.row(k).transpose());
        cost(theta, residual + 3 * j);
      }
      return true;
    }
    const MarkerModel* model;
    const FrameMarkers* frame;
  };

  std::vector<int> AllMarkers() const {
    std::vector<int> all(model_.num_markers);
    for (int k = 0; k < model_.num_markers; ++k) all[k] = k;
    return all;
  }

  // P (3|J present| x 3|ks|) for the markers ks (ascending) and the factor
  // of their normal matrix: rows for the jaw markers among ks.
  Eigen::MatrixXd Projection(const Eigen::LLT<Eigen::MatrixXd>& factor,
                             const std::vector<int>& ks) const {
    const Eigen::MatrixXd& b = model_.unskinned_displacement;
    std::vector<int> jaw;
    for (int k : ks) {
      if (in_jaw_[k]) jaw.push_back(k);
    }
    Eigen::MatrixXd b_jaw(3 * jaw.size(), model_.num_shapes);
    for (size_t j = 0; j < jaw.size(); ++j) b_jaw.middleRows<3>(3 * j) = b.middleRows<3>(3 * jaw[j]);
    Eigen::MatrixXd b_present(3 * ks.size(), model_.num_shapes);
    for (size_t i = 0; i < ks.size(); ++i) b_present.middleRows<3>(3 * i) = b.middleRows<3>(3 * ks[i]);
    const Eigen::MatrixXd g = factor.solve(b_jaw.transpose());  // N x 3|J|
    return g.transpose() * b_present.transpose();
  }

  // Fills frame->base and frame->dynamic_projection from P.
  void SplitProjection(const Eigen::MatrixXd& projection, FrameMarkers* frame) const {
    const int n = static_cast<int>(frame->ks.size());
    const int rows = 3 * static_cast<int>(frame->jaw.size());
    frame->base.resize(rows);
    for (size_t j = 0; j < frame->jaw.size(); ++j) {
      frame->base.segment<3>(3 * j) = model_.neutral.row(frame->ks[frame->jaw[j]]).transpose();
    }
    for (int i = 0; i < n; ++i) {
      const int k = frame->ks[i];
      if (model_.jaw_weight[k] > 0) {
        frame->dynamic.push_back(i);
        continue;
      }
      const Vec3 d = frame->points[i] - model_.neutral.row(k).transpose();
      frame->base.noalias() += projection.middleCols<3>(3 * i) * d;
    }
    frame->dynamic_projection.resize(rows, 3 * frame->dynamic.size());
    for (size_t i = 0; i < frame->dynamic.size(); ++i) {
      frame->dynamic_projection.middleCols<3>(3 * i) =
          projection.middleCols<3>(3 * frame->dynamic[i]);
    }
  }

  // The factor with the missing markers' terms taken out.
  Eigen::LLT<Eigen::MatrixXd> PartialFactor(const std::vector<int>& ks) const {
    std::vector<char> present(model_.num_markers, 0);
    for (int k : ks) present[k] = 1;
    return Eigen::LLT<Eigen::MatrixXd>(
        NormalWithout(normal_, model_.unskinned_displacement, present));
  }

  const MarkerModel& model_;
  const JawOptions& options_;
  Pose lower_, upper_;
  std::vector<char> in_jaw_;
  Eigen::MatrixXd normal_;
  Eigen::MatrixXd full_projection_;  // P over all markers
};

double Median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

// Fits on markedly fewer jaw markers than the shot's median, or with a
// residual far above its median, are not trusted (jaw_fit.h): they become
// interpolated frames with the reason said.
void RejectUnreliableFits(const JawOptions& options, std::vector<JawFit>* frames) {
  std::vector<double> counts, residuals;
  for (const JawFit& fit : *frames) {
    if (!fit.ok) continue;
    counts.push_back(fit.jaw_markers);
    residuals.push_back(fit.rms_mm);
  }
  if (counts.empty()) return;
  const double usual_count = Median(counts);
  const double usual_residual = Median(residuals);
  for (JawFit& fit : *frames) {
    if (!fit.ok) continue;
    if (fit.jaw_markers < options.min_marker_fraction * usual_count) {
      fit.ok = false;
      fit.reason = fmt::format(
          "{} jaw markers, fewer than {} x the shot's median {}: fit not trusted",
          fit.jaw_markers, options.min_marker_fraction, usual_count);
    } else if (options.max_residual_ratio > 0 &&
               fit.rms_mm > options.max_residual_ratio * usual_residual) {
      fit.ok = false;
      fit.reason = fmt::format(
          "jaw-marker residual {:.3f} mm, above {} x the shot's median {:.3f} mm: fit not "
          "trusted",
          fit.rms_mm, options.max_residual_ratio, usual_residual);
    }
  }
}

// Linear interpolation of the poses of frames with !ok by frame number,
// held at the ends.
void InterpolateFailedJaw(std::vector<JawFit>* frames) {
  std::vector<int> good;
  for (size_t i = 0; i < frames->size(); ++i) {
    if ((*frames)[i].ok) good.push_back(static_cast<int>(i));
  }
  if (good.empty()) return;
  size_t next = 0;
  for (size_t i = 0; i < frames->size(); ++i) {
    while (next < good.size() && good[next] < static_cast<int>(i)) ++next;
    JawFit& fit = (*frames)[i];
    if (fit.ok) continue;
    if (next == 0) {
      fit.pose = (*frames)[good.front()].pose;
    } else if (next == good.size()) {
      fit.pose = (*frames)[good.back()].pose;
    } else {
      const JawFit& a = (*frames)[good[next - 1]];
      const JawFit& b = (*frames)[good[next]];
      const double s = static_cast<double>(fit.frame - a.frame) / std::max(1, b.frame - a.frame);
      const Pose pa = a.pose.ToArray(), pb = b.pose.ToArray();
      Pose p;
      for (int k = 0; k < 3; ++k) p[k] = (1 - s) * pa[k] + s * pb[k];
      fit.pose = JawPose::FromArray(p);
    }
  }
}

// The temporal prior over the sequence (jaw_fit.h).
void SmoothJaw(double mu, const Pose& lower, const Pose& upper, std::vector<JawFit>* frames) {
  const int n = static_cast<int>(frames->size());
  if (mu <= 0 || n < 3) return;
  std::vector<Pose> theta(n);
  ceres::Problem problem;
  for (int f = 0; f < n; ++f) {
    theta[f] = (*frames)[f].pose.ToArray();
    problem.AddParameterBlock(theta[f].data(), 3);
    for (int i = 0; i < 3; ++i) {
      problem.SetParameterLowerBound(theta[f].data(), i, lower[i]);
      problem.SetParameterUpperBound(theta[f].data(), i, upper[i]);
    }
    const JawFit& fit = (*frames)[f];
    if (!fit.ok) continue;
    const Mat3 h = fit.information + 1e-9 * Mat3::Identity();
    const Mat3 lt = Eigen::LLT<Mat3>(h).matrixL().transpose();
    const Pose estimate = fit.pose.ToArray();
    problem.AddResidualBlock(
        new ceres::AutoDiffCostFunction<JawDataPrior, 3, 3>(
            new JawDataPrior(lt, Vec3(estimate[0], estimate[1], estimate[2]))),
        nullptr, theta[f].data());
  }
  for (int f = 1; f + 1 < n; ++f) {
    problem.AddResidualBlock(
        new ceres::AutoDiffCostFunction<JawSecondDifference, 3, 3, 3, 3>(
            new JawSecondDifference(std::sqrt(mu))),
        nullptr, theta[f - 1].data(), theta[f].data(), theta[f + 1].data());
  }
  ceres::Solver::Options solver;
  solver.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  solver.sparse_linear_algebra_library_type =
      ceres::IsSparseLinearAlgebraLibraryTypeAvailable(ceres::SUITE_SPARSE)
          ? ceres::SUITE_SPARSE
          : ceres::EIGEN_SPARSE;
  solver.max_num_iterations = 50;
  solver.logging_type = ceres::SILENT;
  solver.function_tolerance = 1e-14;
  solver.parameter_tolerance = 1e-12;
  ceres::Solver::Summary summary;
  ceres::Solve(solver, &problem, &summary);
  for (int f = 0; f < n; ++f) (*frames)[f].pose = JawPose::FromArray(theta[f]);
}

}  // namespace

JawOutput RunJaw(const Actor& actor, const MarkerModel& model,
                 const std::vector<BundleFrame>& bundles, const JawOptions& options) {
  if (!options.Check()) throw InputError("invalid jaw options (see the message above)");
  if (!model.jaw_rig) {
    ThrowInputError(actor.dir / "actor.yaml", 0,
                     "actor '{}' has no jaw rig (no jaw in actor.yaml): there is no jaw pose "
                     "to estimate; run `hmc solve` without --jaw",
                     actor.name);
  }
  const auto start = std::chrono::steady_clock::now();
  ThreadLimit thread_limit(options.threads);
  JawOutput out;
  // Bounds: the dataset's jaw poses (and the rest pose), widened.
  for (int i = 0; i < 3; ++i) out.lower[i] = out.upper[i] = 0;
  for (const Shape& shape : actor.shapes) {
    const Pose p = shape.jaw.ToArray();
    for (int i = 0; i < 3; ++i) {
      out.lower[i] = std::min(out.lower[i], p[i]);
      out.upper[i] = std::max(out.upper[i], p[i]);
    }
  }
  for (int i = 0; i < 3; ++i) {
    const double margin = std::max(options.bound_margin * (out.upper[i] - out.lower[i]), 1.0);
    out.lower[i] -= margin;
    out.upper[i] += margin;
  }
  const std::vector<int> jaw_markers = JawMarkers(model, actor, options);
  if (static_cast<int>(jaw_markers.size()) < options.min_jaw_markers) {
    spdlog::warn("jaw: the actor has {} jaw markers (tagged jaw, or lower lip, with jaw "
                 "weight), fewer than min_jaw_markers {}: every frame is interpolated",
                 jaw_markers.size(), options.min_jaw_markers);
  }
  const FrameJawFitter fitter(model, jaw_markers, options, out.lower, out.upper);
  const int num_frames = static_cast<int>(bundles.size());
  out.frames.resize(num_frames);
  ParallelFor(0, num_frames, [&](int64_t f) { out.frames[f] = fitter.Fit(bundles[f]); }, 4);
  RejectUnreliableFits(options, &out.frames);
  InterpolateFailedJaw(&out.frames);
  SmoothJaw(options.smoothness, out.lower, out.upper, &out.frames);
  double sum = 0;
  for (const JawFit& fit : out.frames) {
    if (fit.ok) {
      ++out.num_ok;
      sum += fit.rms_mm;
    } else {
      ++out.num_interpolated;
    }
  }
  out.mean_rms_mm = out.num_ok > 0 ? sum / out.num_ok : 0.0;
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

void WriteJawOutput(const JawOutput& output, const JawOptions& options,
                    const std::filesystem::path& path) {
  const std::filesystem::path dir = path.has_parent_path() ? path.parent_path() : ".";
  EnsureDirectory(dir);
  WriteJawCsv(path, output.JawFrames());
  const std::string stem = path.stem().string();
  OptionFields used;
  JawOptions copy = options;
  copy.Register(&used);
  WriteOptionsUsed(used, dir / (stem + "_options_used.yaml"), "jaw");
  nlohmann::json summary;
  summary["stage"] = "jaw";
  summary["frames"] = output.frames.size();
  summary["fitted"] = output.num_ok;
  summary["interpolated"] = output.num_interpolated;
  summary["mean_residual_mm"] = output.mean_rms_mm;
  summary["seconds"] = output.seconds;
  summary["lower"] = output.lower;
  summary["upper"] = output.upper;
  nlohmann::json interpolated = nlohmann::json::array();
  for (const JawFit& fit : output.frames) {
    if (!fit.ok) interpolated.push_back({{"frame", fit.frame}, {"reason", fit.reason}});
  }
  summary["interpolated_frames"] = interpolated;
  summary["report"] = output.BriefReport();
  WriteFileAtomic(dir / (stem + "_summary.json"), summary.dump(2) + "\n");
}

}  // namespace hmc
