#include "stabilization/pose_trajectory.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>

#include "core/error_stats.h"
#include "stabilization/head_fit.h"

namespace hmc {

namespace {

using Vec6 = Eigen::Matrix<double, 6, 1>;
using Mat6 = Eigen::Matrix<double, 6, 6>;

// x = (omega, v) of the rigid map p -> R (p - c) + c + v about the centre
// c: omega R's rotation vector, v = R c + t - c.
Vec6 Log(const Rigid3& m, const Vec3& c) {
  const Eigen::AngleAxisd aa(m.linear());
  Vec6 out;
  out.head<3>() = aa.angle() * aa.axis();
  out.tail<3>() = m.linear() * c + m.translation() - c;
  return out;
}

Rigid3 Exp(const Vec6& x, const Vec3& c) {
  Rigid3 m = Rigid3::Identity();
  const Vec3 omega = x.head<3>();
  if (omega.norm() > 0) {
    m.linear() = Eigen::AngleAxisd(omega.norm(), omega.normalized()).toRotationMatrix();
  }
  m.translation() = x.tail<3>() + c - m.linear() * c;
  return m;
}

}  // namespace

std::vector<Rigid3> SmoothPoseTrajectory(const std::vector<PoseMeasurement>& measurements,
                                         double tolerance_mm, const Vec3& center,
                                         double lever_mm) {
  std::vector<Rigid3> poses;
  const int n = static_cast<int>(measurements.size());
  for (const PoseMeasurement& m : measurements) poses.push_back(m.pose);
  // Parameters scaled to mm (rotation times the lever) so that the six are
  // comparable: x' = S x, S = diag(lever x 3, 1 x 3).
  Vec6 scale;
  scale << lever_mm, lever_mm, lever_mm, 1, 1, 1;
  const Eigen::DiagonalMatrix<double, 6> s_inv(scale.cwiseInverse());
  // The measurements' information is about the origin: (omega, v_origin)
  // = (omega, v + c x omega).
  Mat6 to_origin = Mat6::Identity();
  to_origin.block<3, 3>(3, 0) = Skew(center);
  std::vector<Mat6> lambda(n, Mat6::Zero());  // scaled Lambda_f about the centre
  int measured = 0;
  for (int f = 0; f < n; ++f) {
    const PoseMeasurement& m = measurements[f];
    if (!m.ok || !(m.variance_mm2 > 0)) continue;
    lambda[f] = s_inv * (to_origin.transpose() * m.information * to_origin / m.variance_mm2) * s_inv;
    ++measured;
  }
  if (measured < 3) return poses;

  // Sigma_p by the method of moments over consecutive measured frames,
  // the better-measured half of the pairs (the smaller trace of the two
  // frames' covariances): where frames the dataset cannot explain come in
  // runs, their own errors would otherwise pass for motion.
  struct Pair {
    Vec6 increment2, noise;  // per frame of gap
    double trace;
  };
  std::vector<Pair> pairs;
  for (int f = 0; f + 1 < n; ++f) {
    const PoseMeasurement& a = measurements[f];
    const PoseMeasurement& b = measurements[f + 1];
    if (lambda[f].isZero() || lambda[f + 1].isZero()) continue;
    const double gap = std::max(1, b.frame - a.frame);
    const Vec6 u = scale.cwiseProduct(Log(b.pose * a.pose.inverse(), center));
    const Vec6 var = lambda[f].fullPivLu().inverse().diagonal() +
                     lambda[f + 1].fullPivLu().inverse().diagonal();
    pairs.push_back({u.cwiseAbs2() / gap, var / gap, var.sum()});
  }
  if (pairs.empty()) return poses;
  std::sort(pairs.begin(), pairs.end(),
            [](const Pair& x, const Pair& y) { return x.trace < y.trace; });
  pairs.resize((pairs.size() + 1) / 2);
  std::vector<std::vector<double>> increments(6), noise(6);
  for (const Pair& pair : pairs) {
    for (int j = 0; j < 6; ++j) {
      increments[j].push_back(pair.increment2[j]);
      noise[j].push_back(pair.noise[j]);
    }
  }
  constexpr double kChiSquare1Median = 0.454936;
  // The smallest step the random walk may have: a thousandth of the
  // tolerance, so the system stays definite where the poses do not move.
  const double floor = 1e-6 * tolerance_mm * tolerance_mm;
  // Nor less than a quarter of the increments' own variance (half their
  // spread): the fits' noise model is approximate (independent noise of
  // one variance per frame), and a prior tighter than the footage shows
  // would flatten slip the markers do show.
  constexpr double kLeast = 0.25;
  Vec6 process_var;
  for (int j = 0; j < 6; ++j) {
    const double total = UpperMedian(&increments[j]) / kChiSquare1Median;
    process_var[j] = std::max({floor, kLeast * total, total - UpperMedian(&noise[j])});
  }

  // Gauss-Newton on the left perturbations, relinearised.
  for (int iteration = 0; iteration < 50; ++iteration) {
    std::vector<Eigen::Triplet<double>> triplets;
    Eigen::VectorXd rhs = Eigen::VectorXd::Zero(6 * n);
    auto add_block = [&](int r, int c, const Mat6& block) {
      for (int i = 0; i < 6; ++i) {
        for (int j = 0; j < 6; ++j) {
          if (block(i, j) != 0) triplets.emplace_back(6 * r + i, 6 * c + j, block(i, j));
        }
      }
    };
    for (int f = 0; f < n; ++f) {
      if (lambda[f].isZero()) continue;
      const Vec6 e = scale.cwiseProduct(Log(poses[f] * measurements[f].pose.inverse(), center));
      add_block(f, f, lambda[f]);
      rhs.segment<6>(6 * f) -= lambda[f] * e;
    }
    for (int f = 0; f + 1 < n; ++f) {
      const double gap = std::max(1, measurements[f + 1].frame - measurements[f].frame);
      const Mat6 p = Mat6(process_var.cwiseInverse().asDiagonal()) / gap;
      const Vec6 u = scale.cwiseProduct(Log(poses[f + 1] * poses[f].inverse(), center));
      add_block(f, f, p);
      add_block(f + 1, f + 1, p);
      add_block(f, f + 1, -p);
      add_block(f + 1, f, -p);
      rhs.segment<6>(6 * f) += p * u;
      rhs.segment<6>(6 * (f + 1)) -= p * u;
    }
    Eigen::SparseMatrix<double> a(6 * n, 6 * n);
    a.setFromTriplets(triplets.begin(), triplets.end());
    const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(a);
    if (solver.info() != Eigen::Success) return poses;
    const Eigen::VectorXd delta = solver.solve(rhs);
    double largest = 0;
    for (int f = 0; f < n; ++f) {
      const Vec6 d = delta.segment<6>(6 * f);
      largest = std::max(largest, d.head<3>().norm() + d.tail<3>().norm());
      poses[f] = Exp(scale.cwiseInverse().cwiseProduct(d), center) * poses[f];
    }
    if (largest <= tolerance_mm) break;
  }
  return poses;
}

}  // namespace hmc
