// The Ceres cost of one jaw marker (stabilization/jaw_fit.h).
#pragma once

#include <ceres/ceres.h>

#include "core/jaw.h"
#include "core/types.h"

namespace hmc {

// Rotation by angle (rad) about the unit axis a (Rodrigues):
// R = cos(phi) I + sin(phi) [a]_x + (1 - cos(phi)) a a^T.
template <typename T>
Eigen::Matrix<T, 3, 3> AxisRotation(const Vec3& a, const T& phi) {
  using std::cos;
  using std::sin;
  const T c = cos(phi), s = sin(phi);
  Eigen::Matrix<T, 3, 3> cross;
  cross << T(0), T(-a.z()), T(a.y()), T(a.z()), T(0), T(-a.x()), T(-a.y()), T(a.x()), T(0);
  return c * Eigen::Matrix<T, 3, 3>::Identity() + s * cross +
         (T(1) - c) * (a * a.transpose()).template cast<T>();
}

// Residual of marker k for the jaw pose theta = (open_deg, lateral_deg,
// protrude_mm), its unskinned position u, jaw weight w and moment m:
//   r(theta) = p - [(1 - w) u + w (R u + t) + (R m - m)],
//   R = Rot(axis_y, lateral) Rot(axis_x, open),
//   t = pivot - R pivot + protrude axis_z      (JawRig::Transform).
struct JawMarkerCost {
  JawMarkerCost(const JawRig& rig, const Vec3& p, const Vec3* u, double w,
                const Vec3& m)
      : rig_(rig), p_(p), u_(u), w_(w), m_(m) {}

  template <typename T>
  bool operator()(const T* theta, T* residual) const {
    const T to_rad = T(M_PI / 180.0);
    const Eigen::Matrix<T, 3, 3> r = AxisRotation<T>(rig_.axes.col(1), theta[1] * to_rad) *
                                     AxisRotation<T>(rig_.axes.col(0), theta[0] * to_rad);
    const Eigen::Matrix<T, 3, 1> pivot = rig_.pivot.cast<T>();
    const Eigen::Matrix<T, 3, 1> t =
        pivot - r * pivot + theta[2] * rig_.axes.col(2).cast<T>();
    const Eigen::Matrix<T, 3, 1> u = u_->cast<T>();
    const Eigen::Matrix<T, 3, 1> m = m_.cast<T>();
    const Eigen::Matrix<T, 3, 1> skinned =
        (T(1) - T(w_)) * u + T(w_) * (r * u + t) + (r * m - m);
    for (int i = 0; i < 3; ++i) residual[i] = T(p_[i]) - skinned[i];
    return true;
  }

  static ceres::CostFunction* Create(const JawRig& rig, const Vec3& p, const Vec3* u,
                                     double w, const Vec3& m) {
    return new ceres::AutoDiffCostFunction<JawMarkerCost, 3, 3>(
        new JawMarkerCost(rig, p, u, w, m));
  }

 private:
  const JawRig& rig_;
  Vec3 p_;
  const Vec3* u_;  // updated between the alternation's pose steps
  double w_;
  Vec3 m_;
};

// The temporal prior's data term of frame f: r = L^T (theta - th), with
// H_f = L L^T (so |r|^2 = (theta - th)^T H_f (theta - th)).
struct JawDataPrior {
  JawDataPrior(const Mat3& lt, const Vec3& estimate) : lt_(lt), estimate_(estimate) {}
  template <typename T>
  bool operator()(const T* theta, T* residual) const {
    for (int i = 0; i < 3; ++i) {
      residual[i] = T(0);
      for (int j = 0; j < 3; ++j) residual[i] += T(lt_(i, j)) * (theta[j] - T(estimate_[j]));
    }
    return true;
  }
  Mat3 lt_;
  Vec3 estimate_;
};

// The smoothness term: r = sqrt(mu) (theta_a - 2 theta_b + theta_c).
struct JawSecondDifference {
  explicit JawSecondDifference(double sqrt_mu) : sqrt_mu_(sqrt_mu) {}
  template <typename T>
  bool operator()(const T* a, const T* b, const T* c, T* residual) const {
    for (int i = 0; i < 3; ++i) residual[i] = T(sqrt_mu_) * (a[i] - T(2) * b[i] + c[i]);
    return true;
  }
  double sqrt_mu_;
};

}  // namespace hmc
