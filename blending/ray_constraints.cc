// Constraints after the solve: markers seen by one camera
// (blending/ray_constraints.h; docs/method.md, "Constraints after the solve").
#include "blending/ray_constraints.h"

#include <algorithm>
#include <cmath>
#include <map>

#include <Eigen/LU>
#include <fmt/format.h>

#include "core/error.h"
#include "core/logging.h"

namespace hmc {

void RayConstraintOptions::Register(OptionFields* fields) {
  fields->SetGroup("rays");
  fields->Add("max_mm", &max_mm,
              "a ray farther than this from the solved marker's surface point is not applied "
              "(a mislabelled dot; mm)");
  fields->Add("depth", &depth,
              "the move along the ray: solve (none: the depth stays the solve's) or dataset "
              "(what the dataset's motion at the marker predicts from the move across it)");
  fields->Add("tolerance_mm", &tolerance_mm,
              "the rays' own error: a surface point is moved to within this of its ray, not onto "
              "it (0: onto the ray; mm)");
}

bool RayConstraintOptions::Check() const {
  if (!(max_mm > 0) || !std::isfinite(max_mm)) {
    spdlog::error("rays options: max_mm must be > 0 and finite");
    return false;
  }
  if (depth != "solve" && depth != "dataset") {
    spdlog::error("rays options: depth must be solve or dataset, not '{}'", depth);
    return false;
  }
  if (!(tolerance_mm >= 0) || !std::isfinite(tolerance_mm)) {
    spdlog::error("rays options: tolerance_mm must be >= 0 and finite");
    return false;
  }
  return true;
}

const char* RayStatusName(RayStatus status) {
  switch (status) {
    case RayStatus::kApplied: return "applied";
    case RayStatus::kObserved: return "observed";
    case RayStatus::kBadFrame: return "bad_frame";
    case RayStatus::kBehind: return "behind";
    case RayStatus::kTooFar: return "too_far";
  }
  return "applied";
}

namespace {

// lambda_j at the surface point s: the barycentric blend of its corners'
// rows.
double RaySiteWeight(const Eigen::SparseMatrix<double, Eigen::RowMajor>& weights,
                     const SurfacePoint& s, const MatX3i& F, int site) {
  double w = 0.0;
  for (int c = 0; c < 3; ++c) w += s.bary(c) * weights.coeff(F(s.face, c), site);
  return w;
}

// The point of the ray o + t d (t >= 0 not required: the caller rejects
// points behind o) nearest to p, and its parameter t.
Vec3 NearestPointOnRay(const Vec3& o, const Vec3& d, const Vec3& p, double* t) {
  *t = (p - o).dot(d);
  return o + *t * d;
}

constexpr double kDepthRidge = 0.3;  // blending/ray_constraints.h

// The move along the unit ray direction d that the motion covariance S
// predicts from the move `across` (perpendicular to d): with u1, u2 a basis
// of the plane across d, E[t | a] = S_da S_aa^-1 a, a = (u1.across,
// u2.across). Zero when S is singular across the ray.
Vec3 DepthFromMotion(const Mat3& S, const Vec3& d, const Vec3& across) {
  const Vec3 u1 = d.unitOrthogonal();
  const Vec3 u2 = d.cross(u1);
  Eigen::Matrix2d saa;
  // The ridge: the move across is itself uncertain (the solve's error is
  // not all the dataset's motion); it keeps the prediction bounded where
  // the motion is almost along the ray.
  const double ridge = kDepthRidge * S.trace() / 3;
  saa << u1.dot(S * u1) + ridge, u1.dot(S * u2), u2.dot(S * u1), u2.dot(S * u2) + ridge;
  const Eigen::RowVector2d sda(d.dot(S * u1), d.dot(S * u2));
  const Eigen::Vector2d a(u1.dot(across), u2.dot(across));
  const double det = saa.determinant();
  if (!(det > 1e-12 * saa.trace() * saa.trace())) return Vec3::Zero();
  return (sda * saa.inverse() * a)(0) * d;
}

}  // namespace

std::vector<Mat3> SiteMotionCovariances(const std::vector<MatX3d>& displacements,
                                        const std::vector<SurfacePoint>& sites, const MatX3i& F) {
  std::vector<Mat3> cov(sites.size(), Mat3::Zero());
  for (const MatX3d& b : displacements) {
    for (size_t k = 0; k < sites.size(); ++k) {
      const Vec3 c = EvaluateSurfacePoint(sites[k], F, b);
      cov[k] += c * c.transpose();
    }
  }
  return cov;
}

std::vector<RayResidual> ApplyRayConstraints(
    const std::vector<RayConstraint>& rays, const std::vector<SurfacePoint>& sites,
    const MatX3i& F, const NaturalNeighbourWeights& nn,
    const std::vector<std::vector<char>>& observed, const std::vector<char>& frame_ok,
    const RayConstraintOptions& options, std::vector<MatX3d>* meshes,
    const std::vector<Mat3>& site_motion) {
  return ApplyRayConstraints(rays, sites, F, nn, observed, frame_ok, options,
                             static_cast<int>(meshes->size()),
                             [&](int f) { return &(*meshes)[f]; }, site_motion);
}

std::vector<RayResidual> ApplyRayConstraints(
    const std::vector<RayConstraint>& rays, const std::vector<SurfacePoint>& sites,
    const MatX3i& F, const NaturalNeighbourWeights& nn,
    const std::vector<std::vector<char>>& observed, const std::vector<char>& frame_ok,
    const RayConstraintOptions& options, int num_frames,
    const std::function<MatX3d*(int f)>& mesh_of, const std::vector<Mat3>& site_motion) {
  const int num_sites = static_cast<int>(sites.size());
  if (nn.weights.cols() != num_sites) {
    throw InputError(fmt::format("ray constraints: {} sites but natural-neighbour weights over {}",
                                 num_sites, nn.weights.cols()));
  }
  if (options.depth == "dataset" && static_cast<int>(site_motion.size()) != num_sites) {
    throw InputError(fmt::format("ray constraints: depth \"dataset\" needs the motion at each of "
                                 "the {} sites, {} given",
                                 num_sites, site_motion.size()));
  }
  std::vector<RayResidual> residuals(rays.size());
  // The constraints of each frame, by index into `rays`.
  std::map<int, std::vector<int>> by_frame;
  for (size_t r = 0; r < rays.size(); ++r) {
    const RayConstraint& ray = rays[r];
    if (ray.marker < 0 || ray.marker >= num_sites) {
      throw InputError(fmt::format("ray constraints: marker index {} out of range (0..{})",
                                   ray.marker, num_sites - 1));
    }
    if (ray.frame_index < 0 || ray.frame_index >= num_frames) {
      throw InputError(fmt::format("ray constraints: frame index {} out of range (0..{})",
                                   ray.frame_index, num_frames - 1));
    }
    by_frame[ray.frame_index].push_back(static_cast<int>(r));
  }
  for (const auto& [f, indices] : by_frame) {
    MatX3d* const mesh_f = mesh_of(f);
    if (!mesh_f) continue;
    MatX3d& mesh = *mesh_f;
    const bool ok = frame_ok.empty() || frame_ok[f];
    // The frame's applicable constraints, one per marker (a marker with
    // two rays in one frame would be a bundle; the first is kept).
    std::vector<int> active;
    std::vector<Vec3> target_move;
    std::map<int, int> marker_taken;
    for (int r : indices) {
      const RayConstraint& ray = rays[r];
      RayResidual& res = residuals[r];
      const Vec3 p = EvaluateSurfacePoint(sites[ray.marker], F, mesh);
      double t = 0.0;
      const Vec3 q = NearestPointOnRay(ray.origin, ray.direction, p, &t);
      res.before_mm = res.after_mm = (p - q).norm();
      if (!ok) {
        res.status = RayStatus::kBadFrame;
      } else if (!observed.empty() && observed[f][ray.marker]) {
        res.status = RayStatus::kObserved;
      } else if (t <= 0) {
        res.status = RayStatus::kBehind;
      } else if (res.before_mm > options.max_mm) {
        res.status = RayStatus::kTooFar;
      } else if (marker_taken.count(ray.marker)) {
        res.status = RayStatus::kObserved;  // a second ray of the marker
      } else {
        marker_taken[ray.marker] = static_cast<int>(active.size());
        active.push_back(r);
        // Soft threshold: what is within the ray's own error stays.
        const double keep = std::min(options.tolerance_mm, res.before_mm);
        Vec3 move = res.before_mm > 0 ? Vec3((q - p) * (1 - keep / res.before_mm))
                                      : Vec3::Zero();
        if (options.depth == "dataset") {
          move += DepthFromMotion(site_motion[ray.marker], ray.direction, move);
        }
        target_move.push_back(move);
      }
    }
    if (active.empty()) continue;
    const int m = static_cast<int>(active.size());
    Eigen::MatrixXd A(m, m);
    Eigen::MatrixXd rhs(m, 3);
    for (int i = 0; i < m; ++i) {
      const SurfacePoint& s = sites[rays[active[i]].marker];
      for (int j = 0; j < m; ++j) A(i, j) = RaySiteWeight(nn.weights, s, F, rays[active[j]].marker);
      rhs.row(i) = target_move[i].transpose();
    }
    // A is about the identity (lambda_i is 1 at its own site when the site
    // is a vertex and falls off within a mesh edge); a singular A (two
    // constrained markers in one triangle) falls back to the
    // least-squares solution.
    const Eigen::FullPivLU<Eigen::MatrixXd> lu(A);
    const Eigen::MatrixXd delta =
        lu.isInvertible() ? Eigen::MatrixXd(lu.solve(rhs))
                          : Eigen::MatrixXd(A.completeOrthogonalDecomposition().solve(rhs));
    for (int v = 0; v < nn.weights.rows(); ++v) {
      for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(nn.weights, v); it;
           ++it) {
        const auto slot = marker_taken.find(static_cast<int>(it.col()));
        if (slot == marker_taken.end() || it.value() == 0.0) continue;
        mesh.row(v) += it.value() * delta.row(slot->second);
      }
    }
    for (int r : indices) {
      const RayConstraint& ray = rays[r];
      const Vec3 p = EvaluateSurfacePoint(sites[ray.marker], F, mesh);
      double t = 0.0;
      residuals[r].after_mm = (p - NearestPointOnRay(ray.origin, ray.direction, p, &t)).norm();
    }
  }
  return residuals;
}

RayConstraintSummary SummarizeRays(const std::vector<RayResidual>& residuals) {
  RayConstraintSummary s;
  s.rays = static_cast<int>(residuals.size());
  for (const RayResidual& r : residuals) {
    switch (r.status) {
      case RayStatus::kApplied:
        ++s.applied;
        s.mean_before_mm += r.before_mm;
        s.mean_after_mm += r.after_mm;
        s.max_before_mm = std::max(s.max_before_mm, r.before_mm);
        s.max_after_mm = std::max(s.max_after_mm, r.after_mm);
        break;
      case RayStatus::kObserved: ++s.observed; break;
      case RayStatus::kBadFrame: ++s.bad_frame; break;
      case RayStatus::kBehind: ++s.behind; break;
      case RayStatus::kTooFar: ++s.too_far; break;
    }
  }
  if (s.applied > 0) {
    s.mean_before_mm /= s.applied;
    s.mean_after_mm /= s.applied;
  }
  return s;
}

std::string RayConstraintSummary::BriefReport() const {
  return fmt::format(
      "{} rays, {} applied (distance to the ray mean {:.3f} -> {:.4f} mm, max {:.3f} -> {:.4f}), "
      "{} of observed markers, {} in bad frames, {} behind, {} farther than max_mm",
      rays, applied, mean_before_mm, mean_after_mm, max_before_mm, max_after_mm, observed,
      bad_frame, behind, too_far);
}

}  // namespace hmc
