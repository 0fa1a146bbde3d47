// Weighted rigid fits and robust reweighting for head stabilization.
//
// WeightedRigidFit: the rotation and translation minimising
//   E(R, t) = sum_k w_k |R a_k + t - b_k|^2
// in closed form (Kabsch 1976; weighted form: Umeyama 1991 without scale):
// centroids a_bar, b_bar with weights w, H = sum_k w_k (a_k - a_bar)
// (b_k - b_bar)^T = U S V^T, R = V diag(1, 1, det(V U^T)) U^T,
// t = b_bar - R a_bar.
//
// Robust weights for iteratively reweighted least squares (Holland & Welsch
// 1977): an M-estimator with loss rho(r) is minimised by repeating the
// weighted fit with w_k = rho'(r_k) / r_k:
//   Huber,  scale c: w = 1 for r <= c, c / r beyond;
//   Cauchy, scale c: w = 1 / (1 + (r / c)^2).
#pragma once

#include <string>

#include <Eigen/Core>

#include "core/types.h"

namespace hmc {

struct RigidFit {
  Rigid3 target_from_source = Rigid3::Identity();
  bool ok = false;  // false: fewer than 3 points with weight, or collinear
};

// a, b: 3 x n source and target points (mm); w: n weights >= 0.
RigidFit WeightedRigidFit(const Eigen::Matrix3Xd& a, const Eigen::Matrix3Xd& b,
                          const Eigen::VectorXd& w);

enum class RobustLoss { kNone, kHuber, kCauchy };
// "none" | "huber" | "cauchy"; false for anything else.
bool ParseRobustLoss(const std::string& name, RobustLoss* loss);
// rho'(r) / r for residual norm r >= 0 (mm) and scale c > 0 (mm).
double RobustWeight(RobustLoss loss, double r, double c);

}  // namespace hmc
