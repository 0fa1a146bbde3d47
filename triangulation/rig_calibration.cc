#include "triangulation/rig_calibration.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <memory>

#include <ceres/ceres.h>
#include <ceres/rotation.h>
#include <Eigen/Geometry>
#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "core/error.h"
#include "core/logging.h"
#include "core/parallel.h"

namespace hmc {

void CalibrateOptions::Register(OptionFields* fields) {
  footage.Register(fields);
  fields->Add("sample", &sample, "frames spread over the shot on which the tags are detected")
      .In(1, 100000);
  fields->Add("refine", &refine,
              "extrinsics | intrinsics (also each camera's focal length and principal point)")
      .OneOf({"extrinsics", "intrinsics"});
  fields->Add("tag_layout", &tag_layout,
              "fixed (the nominal tag poses are trusted: helmet space is theirs) | free (also "
              "solve every tag's pose)")
      .OneOf({"fixed", "free"});
  fields->Add("gauge", &gauge,
              "with tag_layout free: tags (helmet space aligned with the nominal tag layout) | "
              "cam0 (cam0 at its nominal pose)")
      .OneOf({"tags", "cam0"});
  fields->Add("huber_px", &huber_px, "Huber loss scale on a corner's residual (px)").Above(0);
  fields->Add("knock_px", &knock_px,
              "a camera's tag corners moving by more than this between two parts of the shot: "
              "the rig changed (px RMS)")
      .Above(0);
  fields->Add("max_focal_sigma_pct", &max_focal_sigma_pct,
              "refine intrinsics only if the tags determine the focal length to this (%)")
      .Above(0);
  fields->Add("max_iterations", &max_iterations, "Ceres iterations").AtLeast(1);
  fields->Add("max_move_mm", &max_move_mm,
              "a camera solved farther than this from its nominal position is refused "
              "(cameras swapped or duplicated, another rig's calibration) (mm)")
      .Above(0);
  fields->Add("max_turn_deg", &max_turn_deg,
              "a camera solved turned more than this from its nominal is refused likewise (deg)")
      .Above(0).AtMost(180);
  fields->Add("threads", &threads, "worker threads (0 = all cores)").AtLeast(0);
  tags.Register(fields);
}

bool CalibrateOptions::Check() const {
  CHECK_OPTION_LIMITS();
  return footage.Check() && tags.Check();
}

std::string CalibrateSummary::BriefReport() const {
  if (change.found) {
    return fmt::format("{} frames sampled: the rig changed: {} moved at frame {} ({:.2f} px)",
                       frames_sampled, change.camera, change.frame, change.shift_px);
  }
  return fmt::format(
      "{} frames sampled, {} tag sightings: corner RMS {:.3f} px, max {:.3f} px; cam1_from_cam0 "
      "changed by {:.3f} mm, {:.4f} deg from the nominal{}{}",
      frames_sampled, observations, rms_px, max_px, relative_moved_mm, relative_turned_deg,
      intrinsics_note.empty() ? "" : "; ", intrinsics_note);
}

namespace {

double AngleDeg(const Mat3& a, const Mat3& b) {
  return Eigen::AngleAxisd(a * b.transpose()).angle() * 180 / M_PI;
}

// One tag corner seen by one camera:
//   r = Project(K(f, cx, cy), R(q_c) (R(q_t) X + t_t) + t_c) - u     (px)
// q_c, t_c: cam_from_helmet; q_t, t_t: helmet_from_tag; X: the corner in the
// tag frame; focal = (fx, cx, cy) with fy = fx * fy_over_fx, the lens
// model's distortion parameters fixed (core/camera.h).
struct CornerResidual {
  Vec3 corner_in_tag;
  Vec2 observed;
  CameraModel model;
  std::array<double, kNumCameraParams> intrinsics;  // distortion used from here
  double fy_over_fx;

  template <typename T>
  bool operator()(const T* cam_q, const T* cam_t, const T* tag_q, const T* tag_t,
                  const T* focal, T* residual) const {
    const Eigen::Map<const Eigen::Quaternion<T>> qc(cam_q), qt(tag_q);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> tc(cam_t), tt(tag_t);
    const Eigen::Matrix<T, 3, 1> x = corner_in_tag.cast<T>();
    const Eigen::Matrix<T, 3, 1> p_cam = qc * (qt * x + tt) + tc;
    T params[kNumCameraParams];
    params[kFx] = focal[0];
    params[kFy] = focal[0] * fy_over_fx;
    params[kCx] = focal[1];
    params[kCy] = focal[2];
    for (int i = kK1; i < kNumCameraParams; ++i) params[i] = T(intrinsics[i]);
    T pixel[2];
    if (!Camera::Project(model, params, p_cam.data(), pixel)) return false;
    residual[0] = pixel[0] - observed.x();
    residual[1] = pixel[1] - observed.y();
    return true;
  }
};

struct PoseBlock {
  double q[4];  // Eigen order x, y, z, w
  double t[3];
  void Set(const Rigid3& pose) {
    const Eigen::Quaterniond quat(pose.linear());
    q[0] = quat.x();
    q[1] = quat.y();
    q[2] = quat.z();
    q[3] = quat.w();
    for (int i = 0; i < 3; ++i) t[i] = pose.translation()[i];
  }
  Rigid3 Get() const {
    Rigid3 pose = Rigid3::Identity();
    pose.linear() = Eigen::Quaterniond(q[3], q[0], q[1], q[2]).normalized().toRotationMatrix();
    pose.translation() = Vec3(t[0], t[1], t[2]);
    return pose;
  }
};

std::array<Vec3, 4> CornersInTag(double size) {
  const double h = size / 2;
  return {Vec3(-h, h, 0), Vec3(h, h, 0), Vec3(h, -h, 0), Vec3(-h, -h, 0)};
}

struct Solution {
  std::vector<PoseBlock> cams, tags;
  std::vector<std::array<double, 3>> focal;
  bool converged = false;
};

// Solves with cam0 fixed; intrinsics free only if `free_intrinsics`. With
// `focal_sigma` (per camera, relative) set to the covariance's answer.
Solution Solve(const HelmetRig& nominal, const std::vector<TagObservation>& obs,
               const CalibrateOptions& options, bool free_intrinsics,
               std::vector<double>* focal_sigma) {
  Solution s;
  const int nc = static_cast<int>(nominal.cameras.size());
  const int nt = static_cast<int>(nominal.tags.size());
  s.cams.resize(nc);
  s.tags.resize(nt);
  s.focal.resize(nc);
  for (int c = 0; c < nc; ++c) {
    s.cams[c].Set(nominal.cameras[c].cam_from_helmet);
    const FisheyeCamera& k = nominal.cameras[c].camera;
    s.focal[c] = {k.fx, k.cx, k.cy};
  }
  for (int t = 0; t < nt; ++t) s.tags[t].Set(nominal.tags[t].helmet_from_tag);
  const bool fixed_tags = options.tag_layout == "fixed";
  ceres::Problem problem;
  std::vector<bool> tag_used(nt, false), cam_used(nc, false);
  for (const TagObservation& o : obs) {
    const HelmetCamera& hc = nominal.cameras[o.camera];
    const auto corners = CornersInTag(nominal.tags[o.tag].size);
    for (int k = 0; k < 4; ++k) {
      auto* cost = new ceres::AutoDiffCostFunction<CornerResidual, 2, 4, 3, 4, 3, 3>(
          new CornerResidual{corners[k], o.corners[k], hc.camera.model, hc.camera.Params(),
                             hc.camera.fy / hc.camera.fx});
      problem.AddResidualBlock(cost, new ceres::HuberLoss(options.huber_px), s.cams[o.camera].q,
                               s.cams[o.camera].t, s.tags[o.tag].q, s.tags[o.tag].t,
                               s.focal[o.camera].data());
    }
    tag_used[o.tag] = true;
    cam_used[o.camera] = true;
  }
  for (int c = 0; c < nc; ++c) {
    if (!cam_used[c]) continue;
    problem.SetManifold(s.cams[c].q, new ceres::EigenQuaternionManifold);
    if (c == 0 && !fixed_tags) {
      problem.SetParameterBlockConstant(s.cams[c].q);
      problem.SetParameterBlockConstant(s.cams[c].t);
    }
    if (!free_intrinsics) problem.SetParameterBlockConstant(s.focal[c].data());
  }
  for (int t = 0; t < nt; ++t) {
    if (!tag_used[t]) continue;
    problem.SetManifold(s.tags[t].q, new ceres::EigenQuaternionManifold);
    if (fixed_tags) {
      problem.SetParameterBlockConstant(s.tags[t].q);
      problem.SetParameterBlockConstant(s.tags[t].t);
    }
  }
  ceres::Solver::Options solver;
  solver.linear_solver_type = ceres::DENSE_QR;
  solver.max_num_iterations = options.max_iterations;
  solver.function_tolerance = 1e-14;
  solver.gradient_tolerance = 1e-14;
  solver.parameter_tolerance = 1e-14;
  solver.num_threads = 1;
  solver.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(solver, &problem, &summary);
  s.converged = summary.IsSolutionUsable();
  if (free_intrinsics && focal_sigma) {
    focal_sigma->assign(nc, std::numeric_limits<double>::infinity());
    ceres::Covariance::Options cov_options;
    cov_options.algorithm_type = ceres::DENSE_SVD;
    cov_options.null_space_rank = -1;
    ceres::Covariance covariance(cov_options);
    std::vector<std::pair<const double*, const double*>> blocks;
    for (int c = 0; c < nc; ++c) {
      if (cam_used[c]) blocks.push_back({s.focal[c].data(), s.focal[c].data()});
    }
    const int num_residuals = problem.NumResiduals();
    const int num_params = problem.NumParameters();  // ambient; close enough for the dof
    const double s2 = 2 * summary.final_cost / std::max(1, num_residuals - num_params);
    if (covariance.Compute(blocks, &problem)) {
      for (int c = 0; c < nc; ++c) {
        if (!cam_used[c]) continue;
        double block[9];
        covariance.GetCovarianceBlock(s.focal[c].data(), s.focal[c].data(), block);
        // The covariance assumes unit pixel noise; scale by the residuals'.
        (*focal_sigma)[c] = std::sqrt(std::max(0.0, block[0] * s2)) / s.focal[c][0];
      }
    }
  }
  return s;
}

void Residuals(const HelmetRig& rig, const TagObservation& o, double* sum_sq, double* max_px) {
  const HelmetCamera& hc = rig.cameras[o.camera];
  const std::vector<Vec3> corners = rig.tags[o.tag].CornersInHelmet();
  for (int k = 0; k < 4; ++k) {
    Vec2 pixel;
    double e = std::numeric_limits<double>::infinity();
    if (hc.camera.Project(hc.cam_from_helmet * corners[k], &pixel)) e = (pixel - o.corners[k]).norm();
    *sum_sq += e * e;
    *max_px = std::max(*max_px, e);
  }
}

}  // namespace

CalibrateOutput SolveRigFromTags(const HelmetRig& nominal,
                                 const std::vector<TagObservation>& observations,
                                 const CalibrateOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  const int nc = static_cast<int>(nominal.cameras.size());
  const int nt = static_cast<int>(nominal.tags.size());
  if (observations.empty()) throw InputError("calibrate: no helmet tag was detected");
  std::vector<int> per_camera(nc, 0);
  for (const TagObservation& o : observations) {
    HMC_CHECK(o.camera >= 0 && o.camera < nc && o.tag >= 0 && o.tag < nt);
    ++per_camera[o.camera];
  }
  for (int c = 0; c < nc; ++c) {
    if (per_camera[c] == 0) {
      throw InputError("calibrate: camera " + nominal.cameras[c].name + " sees no helmet tag");
    }
  }
  CalibrateOutput out;
  std::vector<double> focal_sigma(nc, 0);
  bool intrinsics = options.refine == "intrinsics";
  Solution s = Solve(nominal, observations, options, intrinsics, &focal_sigma);
  std::string note;
  if (intrinsics) {
    bool determined = true;
    for (int c = 0; c < nc; ++c) {
      note += fmt::format("{}{}: focal length 1-sigma {:.3f} %", c ? ", " : "",
                          nominal.cameras[c].name, 100 * focal_sigma[c]);
      determined = determined && 100 * focal_sigma[c] <= options.max_focal_sigma_pct;
    }
    if (!determined) {
      note = fmt::format(
                 "intrinsics NOT refined: the tags do not determine the focal length to {} % "
                 "(",
                 options.max_focal_sigma_pct) +
             note + "); the nominal intrinsics are kept";
      s = Solve(nominal, observations, options, false, nullptr);
      intrinsics = false;
    } else {
      note = "intrinsics refined (" + note +
             "; on synthetic footage four helmet tags left the focal length 0.1-0.4 % off, "
             "3-6x the covariance's figure, and the poses worse: docs/calibration.md)";
    }
  }
  HelmetRig rig = nominal;
  for (int c = 0; c < nc; ++c) {
    rig.cameras[c].cam_from_helmet = s.cams[c].Get();
    FisheyeCamera& k = rig.cameras[c].camera;
    const double ratio = k.fy / k.fx;
    k.fx = s.focal[c][0];
    k.fy = s.focal[c][0] * ratio;
    k.cx = s.focal[c][1];
    k.cy = s.focal[c][2];
  }
  std::vector<bool> tag_seen(nt, false);
  for (const TagObservation& o : observations) tag_seen[o.tag] = true;
  for (int t = 0; t < nt; ++t) {
    if (tag_seen[t]) rig.tags[t].helmet_from_tag = s.tags[t].Get();
  }
  if (options.tag_layout == "free" && options.gauge == "tags") {
    // helmet_new_from_helmet_solved: aligns the solved corners with the nominal ones.
    std::vector<Vec3> solved, wanted;
    for (int t = 0; t < nt; ++t) {
      if (!tag_seen[t]) continue;
      for (const Vec3& p : rig.tags[t].CornersInHelmet()) solved.push_back(p);
      for (const Vec3& p : nominal.tags[t].CornersInHelmet()) wanted.push_back(p);
    }
    Eigen::Matrix3Xd a(3, solved.size()), b(3, wanted.size());
    for (size_t i = 0; i < solved.size(); ++i) {
      a.col(i) = solved[i];
      b.col(i) = wanted[i];
    }
    if (solved.size() >= 3) {
      Rigid3 align = Rigid3::Identity();
      align.matrix() = Eigen::umeyama(a, b, false);
      for (HelmetCamera& hc : rig.cameras) hc.cam_from_helmet = hc.cam_from_helmet * align.inverse();
      for (int t = 0; t < nt; ++t) {
        if (tag_seen[t]) rig.tags[t].helmet_from_tag = align * rig.tags[t].helmet_from_tag;
      }
    }
  }
  out.rig = rig;

  // Report.
  std::map<int, size_t> frame_index;
  for (const TagObservation& o : observations) frame_index.emplace(o.frame, 0);
  for (auto& [frame, index] : frame_index) {
    index = out.frames.size();
    out.frames.push_back(frame);
  }
  std::vector<std::vector<double>> frame_sq(out.frames.size(), std::vector<double>(nc, 0));
  std::vector<std::vector<int>> frame_n(out.frames.size(), std::vector<int>(nc, 0));
  out.cameras.resize(nc);
  out.tags.resize(nt);
  std::vector<double> cam_sq(nc, 0), tag_sq(nt, 0);
  std::vector<int> tag_n(nt, 0);
  double all_sq = 0;
  for (int t = 0; t < nt; ++t) {
    out.tags[t].id = nominal.tags[t].id;
    out.tags[t].detections.assign(nc, 0);
  }
  for (const TagObservation& o : observations) {
    double sq = 0, mx = 0;
    Residuals(rig, o, &sq, &mx);
    CameraCalibrationReport& cr = out.cameras[o.camera];
    ++cr.detections;
    cam_sq[o.camera] += sq;
    cr.max_px = std::max(cr.max_px, mx);
    TagCalibrationReport& tr = out.tags[o.tag];
    ++tr.detections[o.camera];
    tag_sq[o.tag] += sq;
    ++tag_n[o.tag];
    tr.max_px = std::max(tr.max_px, mx);
    all_sq += sq;
    out.summary.max_px = std::max(out.summary.max_px, mx);
    const size_t f = frame_index[o.frame];
    frame_sq[f][o.camera] += sq;
    frame_n[f][o.camera] += 4;
  }
  for (int c = 0; c < nc; ++c) {
    CameraCalibrationReport& cr = out.cameras[c];
    const HelmetCamera& a = rig.cameras[c];
    const HelmetCamera& b = nominal.cameras[c];
    cr.name = a.name;
    cr.rms_px = std::sqrt(cam_sq[c] / std::max(1, 4 * cr.detections));
    cr.moved_mm = (a.cam_from_helmet.inverse().translation() -
                   b.cam_from_helmet.inverse().translation()).norm();
    cr.turned_deg = AngleDeg(a.cam_from_helmet.linear(), b.cam_from_helmet.linear());
    cr.intrinsics_refined = intrinsics;
    cr.focal_sigma_pct = options.refine == "intrinsics" ? 100 * focal_sigma[c] : 0;
    cr.focal_change_px = a.camera.fx - b.camera.fx;
    cr.principal_change_px = std::hypot(a.camera.cx - b.camera.cx, a.camera.cy - b.camera.cy);
  }
  for (int t = 0; t < nt; ++t) {
    TagCalibrationReport& tr = out.tags[t];
    tr.rms_px = std::sqrt(tag_sq[t] / std::max(1, 4 * tag_n[t]));
    tr.moved_mm = (rig.tags[t].helmet_from_tag.translation() -
                   nominal.tags[t].helmet_from_tag.translation()).norm();
    tr.turned_deg =
        AngleDeg(rig.tags[t].helmet_from_tag.linear(), nominal.tags[t].helmet_from_tag.linear());
  }
  out.frame_rms_px.resize(out.frames.size());
  for (size_t f = 0; f < out.frames.size(); ++f) {
    for (int c = 0; c < nc; ++c) {
      out.frame_rms_px[f].push_back(frame_n[f][c] > 0
                                        ? std::sqrt(frame_sq[f][c] / frame_n[f][c])
                                        : std::numeric_limits<double>::quiet_NaN());
    }
  }
  CalibrateSummary& sum = out.summary;
  sum.frames_sampled = static_cast<int>(out.frames.size());
  sum.observations = static_cast<int>(observations.size());
  sum.rms_px = std::sqrt(all_sq / (4.0 * observations.size()));
  if (nc >= 2) {
    const Rigid3 solved = rig.cameras[1].cam_from_helmet * rig.cameras[0].cam_from_helmet.inverse();
    const Rigid3 nom =
        nominal.cameras[1].cam_from_helmet * nominal.cameras[0].cam_from_helmet.inverse();
    sum.relative_moved_mm = (solved.translation() - nom.translation()).norm();
    sum.relative_turned_deg = AngleDeg(solved.linear(), nom.linear());
  }
  sum.intrinsics_note = note;
  if (!s.converged) spdlog::warn("calibrate: the solve did not converge");
  sum.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

RigChange FindRigChange(const HelmetRig& nominal, const std::vector<TagObservation>& observations,
                        double knock_px) {
  RigChange best;
  const int nc = static_cast<int>(nominal.cameras.size());
  const int nt = static_cast<int>(nominal.tags.size());
  for (int c = 0; c < nc; ++c) {
    // frames in order; per frame the 4 nt corner slots (NaN if not seen).
    std::map<int, std::vector<Vec2>> by_frame;
    for (const TagObservation& o : observations) {
      if (o.camera != c) continue;
      auto& slots = by_frame[o.frame];
      if (slots.empty()) slots.assign(4 * nt, Vec2::Constant(NAN));
      for (int k = 0; k < 4; ++k) slots[4 * o.tag + k] = o.corners[k];
    }
    std::vector<int> frames;
    std::vector<std::vector<Vec2>> series;
    for (auto& [frame, slots] : by_frame) {
      frames.push_back(frame);
      series.push_back(slots);
    }
    const int n = static_cast<int>(frames.size());
    // Each side needs two frames: one frame alone cannot tell a knock from a
    // bad detection (a hand over a tag). Per slot the median of each side.
    auto median = [](std::vector<double> v) {
      std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
      return v[v.size() / 2];
    };
    for (int split = 2; split + 2 <= n; ++split) {
      double sum_sq = 0;
      int slots_both = 0;
      for (int s = 0; s < 4 * nt; ++s) {
        std::vector<double> bx, by, ax, ay;
        for (int i = 0; i < n; ++i) {
          if (!series[i][s].allFinite()) continue;
          (i < split ? bx : ax).push_back(series[i][s].x());
          (i < split ? by : ay).push_back(series[i][s].y());
        }
        if (bx.empty() || ax.empty()) continue;
        sum_sq += Vec2(median(bx) - median(ax), median(by) - median(ay)).squaredNorm();
        ++slots_both;
      }
      if (slots_both == 0) continue;
      const double shift = std::sqrt(sum_sq / slots_both);
      if (shift > knock_px && shift > best.shift_px) {
        best.found = true;
        best.camera = nominal.cameras[c].name;
        best.frame = frames[split];
        best.last_before = frames[split - 1];
        best.shift_px = shift;
      }
    }
  }
  return best;
}

std::vector<TagObservation> DetectRigTags(const TagDetector& detector, const HelmetRig& rig,
                                          int frame, int camera, const cv::Mat& image) {
  std::vector<TagObservation> out;
  const cv::Mat grey = ToGrey8(image);
  for (const TagDetection& d : detector.DetectRectified(grey, rig.cameras[camera].camera)) {
    for (size_t t = 0; t < rig.tags.size(); ++t) {
      if (rig.tags[t].id != d.id) continue;
      out.push_back({frame, camera, static_cast<int>(t), d.corners});
    }
  }
  return out;
}

namespace {

// Detects the tags on the frames `wanted` says (all if null) of `range`.
std::vector<TagObservation> DetectOnFrames(const std::filesystem::path& shot,
                                           const HelmetRig& rig, FootageOptions footage,
                                           const std::string& range,
                                           const std::vector<int>* wanted,
                                           const CalibrateOptions& options, int* frames_read) {
  footage.frames = range;
  FootageReader reader(shot, rig.CameraNames(), footage);
  const int nc = static_cast<int>(rig.cameras.size());
  std::vector<std::unique_ptr<TagDetector>> detectors;
  for (int c = 0; c < nc; ++c) {
    detectors.push_back(std::make_unique<TagDetector>(rig.tag_family, options.tags));
  }
  std::vector<TagObservation> out;
  Progress progress("calibrate: tags", wanted ? static_cast<int64_t>(wanted->size())
                                              : reader.num_frames());
  FootageFrame frame;
  // The other frames are passed over without being turned into images.
  const auto is_wanted = [wanted](int f) {
    return !wanted || std::binary_search(wanted->begin(), wanted->end(), f);
  };
  while (reader.Next(&frame, is_wanted)) {
    ++*frames_read;
    std::vector<std::vector<TagObservation>> per_camera(nc);
    ParallelFor(0, nc, [&](int64_t c) {
      if (frame.images[c].empty()) return;
      per_camera[c] = DetectRigTags(*detectors[c], rig, frame.frame, static_cast<int>(c),
                                    frame.images[c]);
    });
    for (auto& v : per_camera) out.insert(out.end(), v.begin(), v.end());
    progress.Advance();
  }
  progress.Finish();
  for (const std::string& w : reader.warnings()) spdlog::warn("calibrate: {}", w);
  return out;
}

}  // namespace

CalibrateOutput RunCalibrate(const std::filesystem::path& shot,
                             const std::filesystem::path& nominal_path, const HelmetRig& nominal,
                             const CalibrateOptions& options) {
  if (!options.Check()) throw InputError("invalid calibrate options (see the message above)");
  if (nominal.tags.empty()) {
    ThrowInputError(nominal_path, 0,
                    "key 'tags': the calibration has no helmet tags to calibrate from (a "
                    "tagless helmet's stereo calibration is used as it is: hmc run does so)");
  }
  ThreadLimit limit(options.threads);
  const std::vector<std::string> names = nominal.CameraNames();
  int first = 0, last = 0;
  {
    FootageReader reader(shot, names, options.footage);
    for (size_t c = 0; c < nominal.cameras.size(); ++c) {
      const FisheyeCamera& k = nominal.cameras[c].camera;
      const cv::Size size = reader.image_size(static_cast<int>(c));
      if (size.width != k.width || size.height != k.height) {
        ThrowInputError(nominal_path, 0,
                        "keys 'cameras[{}].image_width/image_height' ({} x {}, camera {}) differ "
                        "from the footage {} ({} x {})",
                        c, k.width, k.height, nominal.cameras[c].name,
                        reader.source(static_cast<int>(c)).string(), size.width, size.height);
      }
    }
    first = reader.first_frame();
    last = reader.last_frame();
  }
  const int n = last - first + 1;
  const int sample = std::min(options.sample, n);
  std::vector<int> wanted;
  for (int i = 0; i < sample; ++i) {
    wanted.push_back(first + static_cast<int>(std::floor((i + 0.5) * n / sample)));
  }
  wanted.erase(std::unique(wanted.begin(), wanted.end()), wanted.end());
  int frames_read = 0;
  const std::string range = fmt::format("{}:{}", first, last);
  std::vector<TagObservation> observations =
      DetectOnFrames(shot, nominal, options.footage, range, &wanted, options, &frames_read);
  RigChange change = FindRigChange(nominal, observations, options.knock_px);
  if (change.found && change.frame > change.last_before + 1) {
    // Pin the change to its frame: the frames between the two samples, each
    // assigned to the side whose corners it is nearer.
    // One sampling interval more on each side, so that both sides of the
    // split have two frames wherever the change lies.
    const int gap = change.frame - change.last_before;
    std::vector<TagObservation> between = DetectOnFrames(
        shot, nominal, options.footage,
        fmt::format("{}:{}", std::max(first, change.last_before - gap),
                    std::min(last, change.frame + gap)),
        nullptr, options, &frames_read);
    const RigChange fine = FindRigChange(nominal, between, options.knock_px);
    if (fine.found && fine.camera == change.camera) {
      change.frame = fine.frame;
      change.last_before = fine.last_before;
    }
  }
  CalibrateOutput out;
  if (change.found) {
    out.summary.frames_sampled = static_cast<int>(wanted.size());
    out.summary.observations = static_cast<int>(observations.size());
    out.summary.change = change;
    out.frames = wanted;
    return out;
  }
  out = SolveRigFromTags(nominal, observations, options);
  return out;
}

std::string RigDifference::BriefReport() const {
  std::string text = fmt::format("cam1_from_cam0 off by {:.4f} mm, {:.5f} deg", relative_mm,
                                 relative_deg);
  for (size_t c = 0; c < camera_mm.size(); ++c) {
    text += fmt::format("; camera {} off by {:.4f} mm, {:.5f} deg, focal {:+.3f} px", c,
                        camera_mm[c], camera_deg[c], focal_px[c]);
  }
  return text;
}

RigDifference CompareRigs(const HelmetRig& a, const HelmetRig& b) {
  HMC_CHECK(a.cameras.size() == b.cameras.size());
  RigDifference d;
  for (size_t c = 0; c < a.cameras.size(); ++c) {
    const Rigid3& pa = a.cameras[c].cam_from_helmet;
    const Rigid3& pb = b.cameras[c].cam_from_helmet;
    d.camera_mm.push_back((pa.inverse().translation() - pb.inverse().translation()).norm());
    d.camera_deg.push_back(AngleDeg(pa.linear(), pb.linear()));
    d.focal_px.push_back(a.cameras[c].camera.fx - b.cameras[c].camera.fx);
  }
  if (a.cameras.size() >= 2) {
    const Rigid3 ra = a.cameras[1].cam_from_helmet * a.cameras[0].cam_from_helmet.inverse();
    const Rigid3 rb = b.cameras[1].cam_from_helmet * b.cameras[0].cam_from_helmet.inverse();
    d.relative_mm = (ra.translation() - rb.translation()).norm();
    d.relative_deg = AngleDeg(ra.linear(), rb.linear());
  }
  return d;
}

std::string CalibrationReportJson(const CalibrateOutput& out) {
  using nlohmann::json;
  const CalibrateSummary& s = out.summary;
  json report = {{"stage", "calibrate"},
                 {"frames_sampled", s.frames_sampled},
                 {"tag_sightings", s.observations},
                 {"rms_px", s.rms_px},
                 {"max_px", s.max_px},
                 {"cam1_from_cam0_change_mm", s.relative_moved_mm},
                 {"cam1_from_cam0_change_deg", s.relative_turned_deg},
                 {"intrinsics", s.intrinsics_note},
                 {"seconds", s.seconds}};
  report["rig_change"] = {{"found", s.change.found},
                          {"camera", s.change.camera},
                          {"frame", s.change.frame},
                          {"last_frame_before", s.change.last_before},
                          {"shift_px", s.change.shift_px}};
  json cameras = json::array();
  for (const CameraCalibrationReport& c : out.cameras) {
    cameras.push_back({{"name", c.name},
                       {"detections", c.detections},
                       {"rms_px", c.rms_px},
                       {"max_px", c.max_px},
                       {"moved_mm", c.moved_mm},
                       {"turned_deg", c.turned_deg},
                       {"focal_change_px", c.focal_change_px},
                       {"principal_point_change_px", c.principal_change_px},
                       {"focal_sigma_pct", c.focal_sigma_pct},
                       {"intrinsics_refined", c.intrinsics_refined}});
  }
  report["cameras"] = cameras;
  json tags = json::array();
  for (const TagCalibrationReport& t : out.tags) {
    tags.push_back({{"id", t.id},
                    {"detections", t.detections},
                    {"rms_px", t.rms_px},
                    {"max_px", t.max_px},
                    {"moved_mm", t.moved_mm},
                    {"turned_deg", t.turned_deg}});
  }
  report["tags"] = tags;
  json frames = json::array();
  for (size_t f = 0; f < out.frames.size(); ++f) {
    json row = {{"frame", out.frames[f]}};
    if (f < out.frame_rms_px.size()) {
      json rms = json::array();
      for (double e : out.frame_rms_px[f]) {
        if (std::isnan(e)) {
          rms.push_back(nullptr);
        } else {
          rms.push_back(e);
        }
      }
      row["rms_px"] = rms;
    }
    frames.push_back(row);
  }
  report["frames"] = frames;
  if (out.has_truth) {
    report["truth"] = {{"cam1_from_cam0_mm", out.truth.relative_mm},
                       {"cam1_from_cam0_deg", out.truth.relative_deg},
                       {"camera_mm", out.truth.camera_mm},
                       {"camera_deg", out.truth.camera_deg},
                       {"focal_px", out.truth.focal_px}};
  }
  return report.dump(1) + "\n";
}

}  // namespace hmc
