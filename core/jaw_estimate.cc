#include "core/jaw_estimate.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <functional>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <fmt/format.h>

namespace hmc {

namespace jaw_estimate_detail {

std::string Lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

const std::vector<std::string> kOpenWords = {"open", "drop"};
const std::vector<std::string> kLeftWords = {"left", "sideways_l"};
const std::vector<std::string> kRightWords = {"right", "sideways_r"};
const std::vector<std::string> kForwardWords = {"forward", "thrust", "protru"};

// The shortest shape name that contains "jaw" and one of `words` and none
// of the other jaw motions' words (the unit rather than its combinations
// or in-betweens); -1 if none.
int FindJawShape(const Actor& actor, const std::vector<std::string>& words) {
  auto has_any = [](const std::string& name, const std::vector<std::string>& list) {
    return std::any_of(list.begin(), list.end(), [&](const std::string& w) {
      return name.find(w) != std::string::npos;
    });
  };
  int best = -1;
  for (size_t n = 0; n < actor.shapes.size(); ++n) {
    const std::string name = Lower(actor.shapes[n].name);
    if (name.find("jaw") == std::string::npos || !has_any(name, words)) continue;
    bool other = false;
    for (const auto* list : {&kOpenWords, &kLeftWords, &kRightWords, &kForwardWords}) {
      if (*list != words && has_any(name, *list)) other = true;
    }
    if (!other && (best < 0 || name.size() < actor.shapes[best].name.size())) {
      best = static_cast<int>(n);
    }
  }
  return best;
}

// Levenberg-Marquardt with forward-difference Jacobians on a small
// parameter vector; `residuals` fills r for x.
using ResidualFn = std::function<void(const Eigen::VectorXd&, Eigen::VectorXd*)>;
Eigen::VectorXd Minimise(const ResidualFn& residuals, Eigen::VectorXd x, int iterations = 50) {
  Eigen::VectorXd r, r_try;
  residuals(x, &r);
  double cost = r.squaredNorm();
  double lambda = 1e-3;
  for (int it = 0; it < iterations; ++it) {
    Eigen::MatrixXd jac(r.size(), x.size());
    for (Eigen::Index j = 0; j < x.size(); ++j) {
      Eigen::VectorXd xj = x;
      const double h = 1e-6 * std::max(1.0, std::abs(x[j]));
      xj[j] += h;
      residuals(xj, &r_try);
      jac.col(j) = (r_try - r) / h;
    }
    const Eigen::MatrixXd jtj = jac.transpose() * jac;
    const Eigen::VectorXd g = jac.transpose() * r;
    bool improved = false;
    for (int attempt = 0; attempt < 10 && !improved; ++attempt) {
      Eigen::MatrixXd a = jtj;
      a.diagonal() += lambda * (jtj.diagonal().array() + 1e-12).matrix();
      const Eigen::VectorXd step = -a.ldlt().solve(g);
      const Eigen::VectorXd x_try = x + step;
      residuals(x_try, &r_try);
      const double c = r_try.squaredNorm();
      if (c < cost) {
        improved = true;
        const double gain = cost - c;
        x = x_try;
        r = r_try;
        cost = c;
        lambda = std::max(1e-9, lambda / 3);
        if (gain <= 1e-14 * std::max(1.0, cost) || step.norm() < 1e-12) return x;
      } else {
        lambda *= 10;
      }
    }
    if (!improved) break;
  }
  return x;
}

Mat3 RotationOf(const Vec3& omega) {
  const double angle = omega.norm();
  if (angle < 1e-15) return Mat3::Identity();
  return Eigen::AngleAxisd(angle, omega / angle).toRotationMatrix();
}

// The weight that best scales the chord u onto the displacement d.
double BlendWeight(const Vec3& d, const Vec3& u) {
  const double uu = u.squaredNorm();
  if (uu < 1e-18) return 0.0;
  return std::clamp(d.dot(u) / uu, 0.0, 1.0);
}

struct RotationFit {
  Vec3 omega = Vec3::Zero();  // axis x angle (rad)
  Vec3 pivot = Vec3::Zero();
  double rms_mm = 0;
};

// min over a rotation R = exp([omega]) about `pivot` (pivot fitted too
// unless fixed) of sum_k |d_k - w_k (R - I)(x_k - p)|^2, w_k projected out
// (clamped to [0,1]) or given.
RotationFit FitRotation(const std::vector<Vec3>& x, const std::vector<Vec3>& d,
                        const RotationFit& start, bool fit_pivot,
                        const std::vector<double>* fixed_weights) {
  const size_t n = x.size();
  Vec3 centroid = Vec3::Zero();
  for (const Vec3& p : x) centroid += p;
  centroid /= std::max<size_t>(1, n);
  auto unpack = [&](const Eigen::VectorXd& v, Vec3* omega, Vec3* pivot) {
    *omega = v.head<3>();
    *pivot = fit_pivot ? Vec3(v.tail<3>()) : start.pivot;
  };
  auto residuals = [&](const Eigen::VectorXd& v, Eigen::VectorXd* r) {
    Vec3 omega, pivot;
    unpack(v, &omega, &pivot);
    const Mat3 m = RotationOf(omega) - Mat3::Identity();
    r->resize(3 * n + (fit_pivot ? 1 : 0));
    for (size_t k = 0; k < n; ++k) {
      const Vec3 u = m * (x[k] - pivot);
      const double w = fixed_weights ? (*fixed_weights)[k] : BlendWeight(d[k], u);
      r->segment<3>(3 * k) = d[k] - w * u;
    }
    // The pivot's place along the axis is free: held at the centroid's.
    if (fit_pivot) {
      const Vec3 axis = omega.norm() > 0 ? Vec3(omega.normalized()) : Vec3::UnitX();
      (*r)[3 * n] = axis.dot(pivot - centroid);
    }
  };
  Eigen::VectorXd v(fit_pivot ? 6 : 3);
  v.head<3>() = start.omega;
  if (fit_pivot) v.tail<3>() = start.pivot;
  v = Minimise(residuals, v);
  RotationFit out;
  unpack(v, &out.omega, &out.pivot);
  Eigen::VectorXd r;
  residuals(v, &r);
  out.rms_mm = std::sqrt(r.head(3 * n).squaredNorm() / std::max<size_t>(1, n));
  return out;
}

// The vertices a shape moves by more than `fraction` of its largest move.
std::vector<int> Moving(const MatX3d& displacement, double fraction) {
  const double top = displacement.rowwise().norm().maxCoeff();
  std::vector<int> out;
  for (Eigen::Index v = 0; v < displacement.rows(); ++v) {
    if (top > 0 && displacement.row(v).norm() > fraction * top) out.push_back(static_cast<int>(v));
  }
  return out;
}

// The start of the open fit: the axis the displacements are most nearly
// perpendicular to; the pivot in the plane through the centroid whose
// distance to each vertex before and after its move is the same
// (d . p = d . x + |d|^2 / 2, least squares); the angle from the largest
// chords.
RotationFit StartOpenFit(const std::vector<Vec3>& x, const std::vector<Vec3>& d) {
  Mat3 scatter = Mat3::Zero();
  Vec3 centroid = Vec3::Zero();
  for (size_t k = 0; k < x.size(); ++k) {
    scatter += d[k] * d[k].transpose();
    centroid += x[k];
  }
  centroid /= static_cast<double>(x.size());
  const Eigen::SelfAdjointEigenSolver<Mat3> eig(scatter);
  const Vec3 axis = eig.eigenvectors().col(0);
  Eigen::MatrixXd a(x.size() + 1, 3);
  Eigen::VectorXd b(x.size() + 1);
  for (size_t k = 0; k < x.size(); ++k) {
    a.row(k) = d[k].transpose();
    b[k] = d[k].dot(x[k]) + 0.5 * d[k].squaredNorm();
  }
  a.row(x.size()) = axis.transpose();
  b[x.size()] = axis.dot(centroid);
  RotationFit start;
  start.pivot = a.colPivHouseholderQr().solve(b);
  // The rotation that moves the furthest-moved vertex by its chord.
  size_t far = 0;
  for (size_t k = 0; k < x.size(); ++k) {
    if (d[k].norm() > d[far].norm()) far = k;
  }
  const Vec3 lever = x[far] - start.pivot;
  const Vec3 radial = lever - axis.dot(lever) * axis;
  const double chord = d[far].norm();
  const double angle = 2 * std::asin(std::min(1.0, chord / std::max(1e-9, 2 * radial.norm())));
  // The sign that moves the vertex the way its displacement goes.
  const double sign = axis.cross(radial).dot(d[far]) >= 0 ? 1.0 : -1.0;
  start.omega = sign * angle * axis;
  return start;
}

}  // namespace jaw_estimate_detail

std::string JawRigEstimate::Describe() const {
  const Vec3 h = rig.axes.col(0), v = rig.axes.col(1);
  std::string from = open_shape;
  if (!lateral_shape.empty()) from += ", " + lateral_shape;
  if (!forward_shape.empty()) from += ", " + forward_shape;
  return fmt::format(
      "estimated from {}: pivot ({:.2f}, {:.2f}, {:.2f}) mm, hinge ({:.3f}, {:.3f}, {:.3f}), "
      "vertical ({:.3f}, {:.3f}, {:.3f}), {} vertices weighted, {} shapes with a jaw pose, "
      "open fit RMS {:.3f} mm",
      from, rig.pivot.x(), rig.pivot.y(), rig.pivot.z(), h.x(), h.y(), h.z(), v.x(), v.y(),
      v.z(), (rig.weights.array() > 0).count(), shapes_with_pose, open_rms_mm);
}

std::optional<JawRigEstimate> EstimateJawRig(const Actor& actor) {
  namespace jd = jaw_estimate_detail;
  const int open = jd::FindJawShape(actor, jd::kOpenWords);
  if (open < 0) return std::nullopt;
  const MatX3d& V = actor.neutral.V;
  const MatX3d& d_open = actor.shapes[open].displacement;
  JawRigEstimate out;
  out.open_shape = actor.shapes[open].name;

  // Hinge, pivot and angle on the vertices moved by more than a tenth of
  // the largest move (the skin that barely follows says little).
  std::vector<Vec3> x, d;
  for (int v : jd::Moving(d_open, 0.1)) {
    x.push_back(V.row(v).transpose());
    d.push_back(d_open.row(v).transpose());
  }
  if (x.size() < 6) return std::nullopt;
  const jd::RotationFit fit = jd::FitRotation(x, d, jd::StartOpenFit(x, d), true, nullptr);
  const double angle = fit.omega.norm();
  if (!(angle > 1e-6) || !fit.pivot.allFinite()) return std::nullopt;
  out.open_rms_mm = fit.rms_mm;
  Vec3 hinge = fit.omega / angle;  // opening = a positive rotation about it
  out.rig.pivot = fit.pivot;

  // Weights of every vertex from the open shape.
  const Mat3 m = jd::RotationOf(fit.omega) - Mat3::Identity();
  out.rig.weights = Eigen::VectorXd::Zero(V.rows());
  const double top = d_open.rowwise().norm().maxCoeff();
  for (Eigen::Index v = 0; v < V.rows(); ++v) {
    const Vec3 dv = d_open.row(v).transpose();
    if (dv.norm() <= 1e-3 * top) continue;
    out.rig.weights[v] = jd::BlendWeight(dv, m * (Vec3(V.row(v).transpose()) - fit.pivot));
  }

  // The vertical axis: the sideways shape's rotation, or head space's up.
  Vec3 vertical = Vec3::UnitY();
  int lateral = jd::FindJawShape(actor, jd::kLeftWords);
  double lateral_sign = 1.0;  // + swings to the actor's left
  if (lateral < 0) {
    lateral = jd::FindJawShape(actor, jd::kRightWords);
    lateral_sign = -1.0;
  }
  if (lateral >= 0) {
    const MatX3d& d_lat = actor.shapes[lateral].displacement;
    std::vector<Vec3> xl, dl;
    std::vector<double> wl;
    for (int v : jd::Moving(d_lat, 0.1)) {
      if (out.rig.weights[v] <= 0.5) continue;
      xl.push_back(V.row(v).transpose());
      dl.push_back(d_lat.row(v).transpose());
      wl.push_back(out.rig.weights[v]);
    }
    if (xl.size() >= 6) {
      jd::RotationFit start;
      start.pivot = out.rig.pivot;
      start.omega = Vec3(0, 0.01 * lateral_sign, 0);
      const jd::RotationFit lat = jd::FitRotation(xl, dl, start, false, &wl);
      if (lat.omega.norm() > 1e-6) {
        vertical = lateral_sign * lat.omega.normalized();
        out.lateral_shape = actor.shapes[lateral].name;
      }
    }
  }
  // The hinge points to the actor's left (+x) by convention; opening is
  // then a positive rotation, which fixes the sign above.
  vertical = (vertical - vertical.dot(hinge) * hinge).normalized();
  if (vertical.y() < 0) vertical = -vertical;
  out.rig.axes.col(0) = hinge;
  out.rig.axes.col(1) = vertical;
  out.rig.axes.col(2) = hinge.cross(vertical);
  const int forward = jd::FindJawShape(actor, jd::kForwardWords);
  if (forward >= 0) out.forward_shape = actor.shapes[forward].name;

  // Every shape's jaw pose (open_deg, lateral_deg, protrude_mm) over the
  // vertices the jaw moves (weight > 0), kept where it explains at least
  // half of their displacement.
  std::vector<int> jaw_vertices;
  for (Eigen::Index v = 0; v < V.rows(); ++v) {
    if (out.rig.weights[v] > 0) jaw_vertices.push_back(static_cast<int>(v));
  }
  out.shape_poses.assign(actor.shapes.size(), JawPose());
  for (size_t n = 0; n < actor.shapes.size(); ++n) {
    const MatX3d& dn = actor.shapes[n].displacement;
    double energy = 0;
    for (int v : jaw_vertices) energy += dn.row(v).squaredNorm();
    if (energy <= 0) continue;
    auto residuals = [&](const Eigen::VectorXd& p, Eigen::VectorXd* r) {
      const Rigid3 t = out.rig.Transform(JawPose::FromArray({p[0], p[1], p[2]}));
      r->resize(3 * jaw_vertices.size());
      for (size_t i = 0; i < jaw_vertices.size(); ++i) {
        const int v = jaw_vertices[i];
        const Vec3 xv = V.row(v).transpose();
        r->segment<3>(3 * i) =
            dn.row(v).transpose() - (SkinPoint(t, xv, out.rig.weights[v]) - xv);
      }
    };
    Eigen::VectorXd p = Eigen::VectorXd::Zero(3);
    if (static_cast<int>(n) == open) p[0] = angle * 180 / M_PI;
    p = jd::Minimise(residuals, p);
    Eigen::VectorXd r;
    residuals(p, &r);
    if (r.squaredNorm() <= 0.5 * energy) {
      out.shape_poses[n] = JawPose::FromArray({p[0], p[1], p[2]});
      ++out.shapes_with_pose;
    }
  }
  return out;
}

void ApplyJawRigEstimate(const JawRigEstimate& estimate, Actor* actor) {
  actor->jaw_rig = estimate.rig;
  for (size_t n = 0; n < actor->shapes.size() && n < estimate.shape_poses.size(); ++n) {
    actor->shapes[n].jaw = estimate.shape_poses[n];
  }
}

}  // namespace hmc
