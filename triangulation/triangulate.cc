#include "triangulation/triangulate.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <utility>

#include <ceres/jet.h>
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "core/error.h"
#include "core/file_util.h"
#include "core/parallel.h"
#include "core/text.h"

namespace hmc {

void TriangulateOptions::Register(OptionFields* fields) {
  day.Register(fields);
  fields->Add("gate_px", &gate_px,
              "largest reprojection residual of a view after refinement (px); larger: "
              "mislabel or bad detection, dropped")
      .Above(0).Below(1e4);
  fields->Add("noise_px", &noise_px,
              "expected accuracy of the tracks (px; floor of the depth uncertainty)")
      .AtLeast(0).Below(100);
  fields->Add("min_ray_angle_deg", &min_ray_angle_deg,
              "views whose rays meet at a smaller angle are not triangulated (deg)")
      .AtLeast(0).Below(90);
  fields->Add("max_iterations", &max_iterations, "Gauss-Newton iterations of the refinement")
      .In(1, 1000);
  fields->Add("consistency_p", &consistency_p,
              "false-rejection rate of the stereo consistency test: a bundle whose rays miss "
              "by more than the shot's pixel noise explains at this level is dropped (0 = off)")
      .AtLeast(0).Below(0.5);
  fields->Add("threads", &threads, "worker threads (0 = all cores)").AtLeast(0);
  fields->Add("dot_radius", &dot_radius,
              "painted dot radius (mm), for the rim-depth correction with --actor")
      .AtLeast(0).Below(20);
  fields->Add("dot_fit_radius", &dot_fit_radius,
              "neutral vertices within this of a marker fit the skin's curvature (mm)")
      .Above(0).Below(50);
}

bool TriangulateOptions::Check() const {
  CHECK_OPTION_LIMITS();
  return true;
}

const char* TriangulationStatusName(TriangulationStatus status) {
  switch (status) {
    case TriangulationStatus::kOk: return "ok";
    case TriangulationStatus::kGated: return "gated";
    case TriangulationStatus::kParallel: return "parallel";
    case TriangulationStatus::kBehind: return "behind";
    case TriangulationStatus::kNoRay: return "no_ray";
    case TriangulationStatus::kInconsistent: return "inconsistent";
  }
  return "?";
}

std::string TriangulateSummary::BriefReport() const {
  return fmt::format(
      "{} frames: {} of {} marker-frames triangulated ({} gated, {} inconsistent with pixel "
      "noise {:.3f} px, {} parallel, {} behind, {} without a ray), {} mono rays; residual RMS "
      "{:.3f} px, max {:.3f} px; median depth uncertainty {:.3f} mm; {:.0f} frames/s",
      frames, triangulated, candidates, gated, inconsistent, pixel_noise_px, parallel, behind,
      no_ray, mono, rms_residual_px,
      max_residual_px, median_depth_sigma_mm, seconds > 0 ? frames / seconds : 0.0);
}

std::string TriangulationAccuracy::BriefReport() const {
  return fmt::format(
      "bundle error over {} marker-frames: median {:.4f} mm, RMS {:.4f} mm, p99 {:.4f} mm, max "
      "{:.4f} mm; {} of {} marker-frames seen (full or partial) in every camera triangulated "
      "({:.2f} %), {} of {} full in every camera ({:.2f} %)",
      compared, median_mm, rms_mm, p99_mm, max_mm, seen_both_triangulated, seen_both,
      100 * coverage(), full_both_triangulated, full_both, 100 * full_coverage());
}

namespace {

struct View {
  int camera;
  Vec2 pixel;
};

// Residuals (2 per view) and optionally their 2V x 3 Jacobian at p.
bool Residuals(const HelmetRig& rig, const std::vector<View>& views, const Vec3& p,
               Eigen::VectorXd* r, Eigen::MatrixXd* J) {
  using Jet = ceres::Jet<double, 3>;
  const int n = static_cast<int>(views.size());
  r->resize(2 * n);
  if (J) J->resize(2 * n, 3);
  Jet pj[3];
  for (int i = 0; i < 3; ++i) pj[i] = Jet(p[i], i);
  for (int v = 0; v < n; ++v) {
    const HelmetCamera& hc = rig.cameras[views[v].camera];
    const auto params = hc.camera.Params();
    Jet intrinsics[kNumCameraParams];
    for (int i = 0; i < kNumCameraParams; ++i) intrinsics[i] = Jet(params[i]);
    const Mat3& R = hc.cam_from_helmet.linear();
    const Vec3& t = hc.cam_from_helmet.translation();
    Jet q[3];
    for (int i = 0; i < 3; ++i) {
      q[i] = Jet(t[i]) + R(i, 0) * pj[0] + R(i, 1) * pj[1] + R(i, 2) * pj[2];
    }
    Jet pixel[2];
    if (!Camera::Project(hc.camera.model, intrinsics, q, pixel)) return false;
    for (int k = 0; k < 2; ++k) {
      (*r)[2 * v + k] = pixel[k].a - views[v].pixel[k];
      if (J) J->row(2 * v + k) = pixel[k].v.transpose();
    }
  }
  return true;
}

void Triangulate(const HelmetRig& rig, const std::vector<View>& views,
                 const TriangulateOptions& options, TriangulationRecord* record) {
  const int n = static_cast<int>(views.size());
  record->views = n;
  std::vector<Vec3> origins(n), directions(n);
  for (int v = 0; v < n; ++v) {
    const HelmetCamera& hc = rig.cameras[views[v].camera];
    Vec3 bearing;
    if (!hc.camera.Unproject(views[v].pixel, &bearing)) {
      record->status = TriangulationStatus::kNoRay;
      return;
    }
    const Rigid3 helmet_from_cam = hc.cam_from_helmet.inverse();
    origins[v] = helmet_from_cam.translation();
    directions[v] = (helmet_from_cam.linear() * bearing).normalized();
  }
  double max_angle = 0;
  for (int a = 0; a < n; ++a) {
    for (int b = a + 1; b < n; ++b) {
      const double c = std::clamp(directions[a].dot(directions[b]), -1.0, 1.0);
      max_angle = std::max(max_angle, std::acos(c) * 180 / M_PI);
    }
  }
  record->ray_angle_deg = max_angle;
  if (max_angle < options.min_ray_angle_deg) {
    record->status = TriangulationStatus::kParallel;
    return;
  }
  // Least-squares midpoint: sum_c (I - d d^T) p = sum_c (I - d d^T) o.
  Mat3 A = Mat3::Zero();
  Vec3 b = Vec3::Zero();
  for (int v = 0; v < n; ++v) {
    const Mat3 P = Mat3::Identity() - directions[v] * directions[v].transpose();
    A += P;
    b += P * origins[v];
  }
  Vec3 p = A.ldlt().solve(b);
  for (int v = 0; v < n; ++v) {
    if ((p - origins[v]).dot(directions[v]) <= 0) {
      record->status = TriangulationStatus::kBehind;
      record->p_in_helmet = p;
      return;
    }
  }
  // Gauss-Newton with step halving on the reprojection error.
  Eigen::VectorXd r;
  Eigen::MatrixXd J;
  if (!Residuals(rig, views, p, &r, &J)) {
    record->status = TriangulationStatus::kBehind;
    record->p_in_helmet = p;
    return;
  }
  double cost = r.squaredNorm();
  for (int it = 0; it < options.max_iterations; ++it) {
    const Mat3 JtJ = J.transpose() * J;
    const Vec3 step = -JtJ.ldlt().solve(J.transpose() * r);
    if (!step.allFinite()) break;
    double scale = 1;
    bool improved = false;
    Eigen::VectorXd r_new;
    Eigen::MatrixXd J_new;
    for (int halving = 0; halving < 8; ++halving, scale *= 0.5) {
      const Vec3 candidate = p + scale * step;
      if (Residuals(rig, views, candidate, &r_new, &J_new) && r_new.squaredNorm() <= cost) {
        p = candidate;
        r = r_new;
        J = J_new;
        improved = r_new.squaredNorm() < cost;
        cost = r_new.squaredNorm();
        break;
      }
    }
    if (!improved || (scale * step).norm() < 1e-12) break;
  }
  record->p_in_helmet = p;
  record->residual_px.assign(rig.cameras.size(), std::numeric_limits<double>::quiet_NaN());
  double worst = 0;
  for (int v = 0; v < n; ++v) {
    const double e = r.segment<2>(2 * v).norm();
    record->residual_px[views[v].camera] = e;
    worst = std::max(worst, e);
  }
  for (int v = 0; v < n; ++v) {
    if ((p - origins[v]).dot(directions[v]) <= 0) {
      record->status = TriangulationStatus::kBehind;
      return;
    }
  }
  const int dof = 2 * n - 3;
  const double s2 = std::max(dof > 0 ? cost / dof : 0.0, options.noise_px * options.noise_px);
  const Mat3 cov = s2 * (J.transpose() * J).inverse();
  const double var = directions[0].dot(cov * directions[0]);
  record->depth_sigma_mm = std::sqrt(std::max(0.0, var));
  record->status = worst > options.gate_px ? TriangulationStatus::kGated : TriangulationStatus::kOk;
}

std::string Num(double x) { return fmt::format("{:.9g}", x); }

// The standard normal's quantile at probability P in (0, 1), by bisection
// on erfc (exact to ~1e-12; called a few times per run).
double NormalQuantile(double P) {
  double lo = -40, hi = 40;
  for (int i = 0; i < 100; ++i) {
    const double mid = 0.5 * (lo + hi);
    (0.5 * std::erfc(-mid / std::sqrt(2.0)) < P ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

// The chi^2 distribution's quantile with k degrees of freedom at
// probability P: exact for k = 1 (a squared normal) and k = 2 (an
// exponential), Wilson-Hilferty's cube-root normal approximation above
// (relative error < 1 % for k >= 3 at the probabilities used here).
double ChiSquaredQuantile(int k, double P) {
  if (k == 1) {
    const double z = NormalQuantile(0.5 * (1 + P));
    return z * z;
  }
  if (k == 2) return -2 * std::log1p(-P);
  const double a = 2.0 / (9.0 * k);
  const double c = 1 - a + NormalQuantile(P) * std::sqrt(a);
  return k * c * c * c;
}

// The refined cost E (px^2) of a record: its squared residuals' sum.
double RecordCost(const TriangulationRecord& record) {
  double cost = 0;
  for (double e : record.residual_px) {
    if (!std::isnan(e)) cost += e * e;
  }
  return cost;
}

// Step 5 of the method (triangulate.h): estimates the pixel noise from the
// ok records' costs and marks those beyond the (1 - p) quantile
// inconsistent. Returns the noise (px), 0 when the test did not run.
double RejectInconsistent(double p, std::vector<std::vector<TriangulationRecord>>* records) {
  constexpr int kMinRecords = 20;
  constexpr double kNoiseFloorPx = 0.01;  // centroid precision of 8-bit footage
  if (p <= 0) return 0;
  // Per degrees of freedom 2V - 3: the chi^2 median and (1 - p) quantile.
  std::map<int, std::pair<double, double>> quantiles;
  auto quantiles_of = [&](const TriangulationRecord& r) -> const std::pair<double, double>& {
    const int dof = 2 * r.views - 3;
    auto it = quantiles.find(dof);
    if (it == quantiles.end()) {
      it = quantiles.emplace(dof, std::pair(ChiSquaredQuantile(dof, 0.5),
                                            ChiSquaredQuantile(dof, 1 - p))).first;
    }
    return it->second;
  };
  std::vector<double> normalised;
  for (const auto& frame : *records) {
    for (const TriangulationRecord& r : frame) {
      if (r.status == TriangulationStatus::kOk) {
        normalised.push_back(RecordCost(r) / quantiles_of(r).first);
      }
    }
  }
  if (static_cast<int>(normalised.size()) < kMinRecords) return 0;
  const auto mid = normalised.begin() + normalised.size() / 2;
  std::nth_element(normalised.begin(), mid, normalised.end());
  const double sigma = std::max(std::sqrt(*mid), kNoiseFloorPx);
  for (auto& frame : *records) {
    for (TriangulationRecord& r : frame) {
      if (r.status == TriangulationStatus::kOk &&
          RecordCost(r) > sigma * sigma * quantiles_of(r).second) {
        r.status = TriangulationStatus::kInconsistent;
      }
    }
  }
  return sigma;
}

}  // namespace

TriangulateOutput RunTriangulate(const TriangulateInput& input,
                                 const TriangulateOptions& options) {
  if (!options.Check()) throw InputError("invalid triangulate options (see the message above)");
  HMC_CHECK(input.rig != nullptr && input.tracks != nullptr);
  const HelmetRig& rig = *input.rig;
  std::map<std::string, int> camera_index;
  for (size_t c = 0; c < rig.cameras.size(); ++c) {
    camera_index[rig.cameras[c].name] = static_cast<int>(c);
  }
  // Group the tracks by frame and marker.
  struct Observation {
    std::string marker;
    std::vector<View> views;
  };
  std::map<int, std::map<std::string, std::vector<View>>> by_frame;
  for (const Track2d& t : *input.tracks) {
    const auto it = camera_index.find(t.camera);
    if (it == camera_index.end()) {
      ThrowInputError(input.tracks_path, 0,
                      "camera '{}' of the tracks is not in the calibration (frame {}, marker {})",
                      t.camera, t.frame, t.marker);
    }
    by_frame[t.frame][t.marker].push_back({it->second, t.pixel});
  }
  std::vector<int> frames;
  std::vector<std::vector<Observation>> per_frame;
  for (auto& [frame, markers] : by_frame) {
    frames.push_back(frame);
    per_frame.emplace_back();
    for (auto& [marker, views] : markers) {
      std::sort(views.begin(), views.end(),
                [](const View& a, const View& b) { return a.camera < b.camera; });
      per_frame.back().push_back({marker, std::move(views)});
    }
  }
  const int num_frames = static_cast<int>(frames.size());
  std::vector<std::vector<TriangulationRecord>> records(num_frames);
  std::vector<std::vector<MonoRay>> rays(num_frames);
  ThreadLimit limit(options.threads);
  const auto start = std::chrono::steady_clock::now();
  ParallelFor(0, num_frames, [&](int64_t f) {
    for (const Observation& obs : per_frame[f]) {
      if (obs.views.size() == 1) {
        const HelmetCamera& hc = rig.cameras[obs.views[0].camera];
        Vec3 bearing;
        if (!hc.camera.Unproject(obs.views[0].pixel, &bearing)) continue;
        const Rigid3 helmet_from_cam = hc.cam_from_helmet.inverse();
        rays[f].push_back({frames[f], obs.marker, hc.name, helmet_from_cam.translation(),
                           (helmet_from_cam.linear() * bearing).normalized()});
        continue;
      }
      TriangulationRecord record;
      record.frame = frames[f];
      record.marker = obs.marker;
      record.residual_px.assign(rig.cameras.size(), std::numeric_limits<double>::quiet_NaN());
      Triangulate(rig, obs.views, options, &record);
      if (input.dot_offsets) {
        const auto it = input.dot_offsets->find(obs.marker);
        if (it != input.dot_offsets->end()) record.p_in_helmet -= it->second;
      }
      records[f].push_back(std::move(record));
    }
  }, 4);
  TriangulateOutput out;
  out.summary.pixel_noise_px = RejectInconsistent(options.consistency_p, &records);
  out.summary.seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  TriangulateSummary& s = out.summary;
  s.frames = num_frames;
  double sum_sq = 0;
  int num_views = 0;
  std::vector<double> sigmas;
  for (int f = 0; f < num_frames; ++f) {
    BundleFrame bundle_frame;
    bundle_frame.frame = frames[f];
    for (TriangulationRecord& record : records[f]) {
      ++s.candidates;
      switch (record.status) {
        case TriangulationStatus::kOk:
          ++s.triangulated;
          bundle_frame.bundles[record.marker] = record.p_in_helmet;
          for (double e : record.residual_px) {
            if (std::isnan(e)) continue;
            sum_sq += e * e;
            ++num_views;
            s.max_residual_px = std::max(s.max_residual_px, e);
          }
          sigmas.push_back(record.depth_sigma_mm);
          break;
        case TriangulationStatus::kGated: ++s.gated; break;
        case TriangulationStatus::kParallel: ++s.parallel; break;
        case TriangulationStatus::kBehind: ++s.behind; break;
        case TriangulationStatus::kNoRay: ++s.no_ray; break;
        case TriangulationStatus::kInconsistent: ++s.inconsistent; break;
      }
      out.records.push_back(std::move(record));
    }
    if (!bundle_frame.bundles.empty()) out.bundles.push_back(std::move(bundle_frame));
    s.mono += static_cast<int>(rays[f].size());
    for (MonoRay& ray : rays[f]) out.rays.push_back(std::move(ray));
  }
  s.rms_residual_px = num_views > 0 ? std::sqrt(sum_sq / num_views) : 0;
  if (!sigmas.empty()) {
    std::nth_element(sigmas.begin(), sigmas.begin() + sigmas.size() / 2, sigmas.end());
    s.median_depth_sigma_mm = sigmas[sigmas.size() / 2];
  }
  return out;
}

void WriteRaysCsv(const std::filesystem::path& path, const std::vector<MonoRay>& rays) {
  std::string text = std::string(kRaysCsvHeader) + "\n";
  for (const MonoRay& ray : rays) {
    const Vec3& o = ray.origin_in_helmet;
    const Vec3& d = ray.direction_in_helmet;
    text += fmt::format("{},{},{},{},{},{},{},{},{}\n", ray.frame, ray.marker, ray.camera,
                        Num(o.x()), Num(o.y()), Num(o.z()), Num(d.x()), Num(d.y()), Num(d.z()));
  }
  WriteFileAtomic(path, text);
}

std::vector<MonoRay> ReadRaysCsv(const std::filesystem::path& path) {
  std::vector<MonoRay> rays;
  ForEachCsvRow(path, {"frame", "marker", "camera", "ox", "oy", "oz", "dx", "dy", "dz"},
                [&](const CsvRow& row) {
                  MonoRay ray;
                  ray.frame = row.Int(0);
                  ray.marker = row.NonEmpty(1);
                  ray.camera = row.NonEmpty(2);
                  ray.origin_in_helmet = Vec3(row.Finite(3), row.Finite(4), row.Finite(5));
                  ray.direction_in_helmet = Vec3(row.Finite(6), row.Finite(7), row.Finite(8));
                  if (std::abs(ray.direction_in_helmet.norm() - 1) > 1e-6) {
                    row.Fail("direction (dx,dy,dz) is not a unit vector (norm {})",
                             ray.direction_in_helmet.norm());
                  }
                  rays.push_back(std::move(ray));
                });
  return rays;
}

void WriteTriangulationCsv(const std::filesystem::path& path, const HelmetRig& rig,
                           const std::vector<TriangulationRecord>& records) {
  std::string text = "frame,marker,status,views";
  for (const HelmetCamera& hc : rig.cameras) text += ",residual_" + hc.name + "_px";
  text += ",ray_angle_deg,depth_sigma_mm,x,y,z\n";
  for (const TriangulationRecord& r : records) {
    text += fmt::format("{},{},{},{}", r.frame, r.marker, TriangulationStatusName(r.status),
                        r.views);
    for (size_t c = 0; c < rig.cameras.size(); ++c) {
      const double e = c < r.residual_px.size() ? r.residual_px[c] : NAN;
      text += std::isnan(e) ? std::string(",") : fmt::format(",{:.6f}", e);
    }
    text += fmt::format(",{:.4f},{:.6f},{},{},{}\n", r.ray_angle_deg, r.depth_sigma_mm,
                        Num(r.p_in_helmet.x()), Num(r.p_in_helmet.y()), Num(r.p_in_helmet.z()));
  }
  WriteFileAtomic(path, text);
}

std::vector<Track2d> TracksFromDots(const std::vector<Dot2dTruth>& dots, bool centroid) {
  std::vector<Track2d> tracks;
  for (const Dot2dTruth& d : dots) {
    if (centroid ? !d.has_centroid : !d.visible) continue;
    Track2d t;
    t.frame = d.frame;
    t.camera = d.camera;
    t.marker = d.marker;
    t.pixel = centroid ? d.centroid : d.pixel;
    t.score = 1;
    tracks.push_back(std::move(t));
  }
  return tracks;
}

TriangulationAccuracy EvaluateTriangulation(const std::vector<BundleFrame>& bundles,
                                            const std::vector<BundleFrame>& truth,
                                            const std::vector<Dot2dTruth>& dots,
                                            int num_cameras) {
  TriangulationAccuracy a;
  std::map<int, const BundleFrame*> truth_by_frame;
  for (const BundleFrame& f : truth) truth_by_frame[f.frame] = &f;
  std::map<int, const BundleFrame*> ours_by_frame;
  for (const BundleFrame& f : bundles) ours_by_frame[f.frame] = &f;
  std::vector<double> errors;
  for (const BundleFrame& f : bundles) {
    const auto it = truth_by_frame.find(f.frame);
    if (it == truth_by_frame.end()) continue;
    for (const auto& [marker, p] : f.bundles) {
      const auto jt = it->second->bundles.find(marker);
      if (jt == it->second->bundles.end()) continue;
      errors.push_back((p - jt->second).norm());
    }
  }
  a.compared = static_cast<int>(errors.size());
  if (!errors.empty()) {
    std::sort(errors.begin(), errors.end());
    double sum_sq = 0;
    for (double e : errors) sum_sq += e * e;
    a.rms_mm = std::sqrt(sum_sq / errors.size());
    a.median_mm = errors[errors.size() / 2];
    a.p99_mm = errors[std::min(errors.size() - 1, static_cast<size_t>(0.99 * errors.size()))];
    a.max_mm = errors.back();
  }
  std::map<std::pair<int, std::string>, std::pair<int, int>> seen;  // (seen, full) cameras
  for (const Dot2dTruth& d : dots) {
    auto& counts = seen[{d.frame, d.marker}];
    counts.first += d.disc != DotDiscState::kHidden;
    counts.second += d.disc == DotDiscState::kFull;
  }
  for (const auto& [key, counts] : seen) {
    if (counts.first < num_cameras) continue;
    const auto it = ours_by_frame.find(key.first);
    const bool triangulated = it != ours_by_frame.end() && it->second->bundles.count(key.second);
    ++a.seen_both;
    a.seen_both_triangulated += triangulated;
    if (counts.second < num_cameras) continue;
    ++a.full_both;
    a.full_both_triangulated += triangulated;
  }
  return a;
}

}  // namespace hmc
