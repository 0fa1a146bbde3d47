#include "stabilization/head_fit.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

namespace hmc {

namespace {

// Q = W - W B G^-1 B^T W (head_fit.h) applied to the columns of V, and the
// shape weights c = G^-1 B^T W d, for fixed weights w. Two equal forms:
// with N shapes <= 3n coordinates G (N x N) is factored; otherwise the
// push-through identity gives Q = lambda M^-1 and c = B^T M^-1 d with
// M = B B^T + lambda W^-1 (3n x 3n), the cheaper factorisation for large
// datasets. Markers of zero weight must be left out by the caller (W^-1).
class ExpressionProjection {
 public:
  ExpressionProjection(const Eigen::MatrixXd& b, const Eigen::VectorXd& w, double ridge)
      : b_(b), ridge_(ridge), w3_(Eigen::VectorXd(3 * w.size())) {
    for (Eigen::Index i = 0; i < w.size(); ++i) w3_.segment<3>(3 * i).setConstant(w[i]);
    shape_space_ = b.cols() <= b.rows();
    if (b.cols() == 0) return;
    if (shape_space_) {
      // G's lower half by a rank-3n update (half a general product).
      const Eigen::MatrixXd root_wb = w3_.cwiseSqrt().asDiagonal() * b;
      Eigen::MatrixXd g = Eigen::MatrixXd::Zero(b.cols(), b.cols());
      g.selfadjointView<Eigen::Lower>().rankUpdate(root_wb.transpose());
      g.diagonal().array() += ridge;
      factor_.compute(g);
    } else {
      Eigen::MatrixXd m = b * b.transpose();
      m.diagonal().array() += ridge * w3_.cwiseInverse().array();
      factor_.compute(m);
    }
  }

  // Q V for V: 3n x m.
  Eigen::MatrixXd Apply(const Eigen::MatrixXd& v) const {
    if (b_.cols() == 0) return w3_.asDiagonal() * v;
    if (!shape_space_) return ridge_ * factor_.solve(v);
    const Eigen::MatrixXd wv = w3_.asDiagonal() * v;
    return wv - w3_.asDiagonal() * (b_ * factor_.solve(b_.transpose() * wv));
  }

  // c for the residual-free offsets d (3n).
  Eigen::VectorXd ShapeWeights(const Eigen::VectorXd& d) const {
    if (b_.cols() == 0) return Eigen::VectorXd();
    if (!shape_space_) return b_.transpose() * factor_.solve(d);
    return factor_.solve(b_.transpose() * (w3_.asDiagonal() * d));
  }

 private:
  const Eigen::MatrixXd& b_;
  double ridge_;
  Eigen::VectorXd w3_;
  bool shape_space_ = true;
  Eigen::LLT<Eigen::MatrixXd> factor_;
};

// How far `to` moves the furthest of the points a from where `from` put
// them (mm).
double FurthestMoveMm(const Rigid3& from, const Rigid3& to, const Eigen::Matrix3Xd& a) {
  return ((to * a) - (from * a)).colwise().norm().maxCoeff();
}

}  // namespace

HeadFitResult FitHeadAndExpression(const Eigen::Matrix3Xd& a, const Eigen::Matrix3Xd& q,
                                   const Eigen::MatrixXd& b, const Eigen::VectorXd& s,
                                   const Rigid3& start, const HeadFitOptions& options,
                                   const Eigen::VectorXd& start_residuals_mm) {
  HeadFitResult out;
  // Markers of zero prior weight take no part in E(T, c).
  std::vector<int> used;
  for (Eigen::Index i = 0; i < s.size(); ++i) {
    if (s[i] > 0) used.push_back(static_cast<int>(i));
  }
  const int n = static_cast<int>(used.size());
  const int num_shapes = static_cast<int>(b.cols());
  out.weights = Eigen::VectorXd::Zero(s.size());
  out.residuals_mm = Eigen::VectorXd::Zero(s.size());
  out.shape_weights = Eigen::VectorXd::Zero(num_shapes);
  out.head_from_helmet = start;
  if (n < 3) return out;

  Eigen::Matrix3Xd a_used(3, n), q_used(3, n);
  Eigen::MatrixXd b_used(3 * n, num_shapes);
  Eigen::VectorXd s_used(n);
  for (int i = 0; i < n; ++i) {
    a_used.col(i) = a.col(used[i]);
    q_used.col(i) = q.col(used[i]);
    if (num_shapes > 0) b_used.middleRows<3>(3 * i) = b.middleRows<3>(3 * used[i]);
    s_used[i] = s[used[i]];
  }
  const bool robust = options.loss != RobustLoss::kNone;
  auto robust_weights = [&](const Eigen::VectorXd& r) {
    Eigen::VectorXd w = s_used;
    if (robust) {
      for (int i = 0; i < n; ++i) {
        w[i] *= RobustWeight(options.loss, r[i], options.loss_scale_mm);
      }
    }
    return w;
  };

  Rigid3 t = start;
  Eigen::VectorXd w = s_used;
  if (start_residuals_mm.size() == s.size()) {
    Eigen::VectorXd r(n);
    for (int i = 0; i < n; ++i) r[i] = start_residuals_mm[used[i]];
    w = robust_weights(r);
  }
  // d = T a - q (3n) and the residual norms |d_i - B_i c(T)|.
  auto evaluate = [&](const ExpressionProjection& projection, Eigen::VectorXd* d,
                      Eigen::VectorXd* c, Eigen::VectorXd* r) {
    const Eigen::Matrix3Xd p = t * a_used;
    d->resize(3 * n);
    for (int i = 0; i < n; ++i) d->segment<3>(3 * i) = p.col(i) - q_used.col(i);
    *c = projection.ShapeWeights(*d);
    r->resize(n);
    for (int i = 0; i < n; ++i) {
      Vec3 ri = d->segment<3>(3 * i);
      if (num_shapes > 0) ri -= b_used.middleRows<3>(3 * i) * *c;
      (*r)[i] = ri.norm();
    }
    return p;
  };
  // Gauss-Newton on E(T) for the fixed weights of `projection`; false
  // where the pose is not determined (collinear or too few weighted
  // markers).
  auto solve_weighted = [&](const ExpressionProjection& projection) {
    for (int step = 0; step < options.max_iterations; ++step) {
      Eigen::VectorXd d, c, r;
      const Eigen::Matrix3Xd p = evaluate(projection, &d, &c, &r);
      // A small rotation about the centroid, scaled by the markers' RMS
      // lever so that all six parameters are in mm.
      const Vec3 centroid = p.rowwise().mean();
      const double lever =
          std::max(1e-9, std::sqrt((p.colwise() - centroid).colwise().squaredNorm().mean()));
      Eigen::MatrixXd jac(3 * n, 6);
      for (int i = 0; i < n; ++i) {
        jac.block<3, 3>(3 * i, 0) = -Skew(p.col(i) - centroid) / lever;
        jac.block<3, 3>(3 * i, 3).setIdentity();
      }
      const Eigen::MatrixXd qj = projection.Apply(jac);
      const Eigen::Matrix<double, 6, 6> h = jac.transpose() * qj;
      const Eigen::Matrix<double, 6, 1> g = qj.transpose() * d;
      const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>> eig(h);
      if (eig.eigenvalues()[0] <= 1e-12 * std::max(1.0, eig.eigenvalues()[5])) return false;
      const Eigen::Matrix<double, 6, 1> delta = -h.ldlt().solve(g);
      const Vec3 omega = delta.head<3>() / lever;
      Rigid3 move = Rigid3::Identity();
      if (omega.norm() > 0) {
        move.linear() = Eigen::AngleAxisd(omega.norm(), omega.normalized()).toRotationMatrix();
      }
      move.translation() = centroid - move.linear() * centroid + delta.tail<3>();
      const Rigid3 before = t;
      t = move * t;
      ++out.gauss_newton_steps;
      // The reduced problem is nearly linear: a step a tenth of the
      // tolerance ends it.
      if (FurthestMoveMm(before, t, a_used) <= 0.1 * options.tolerance_mm) break;
    }
    return true;
  };

  // Iteratively reweighted: each round solves the weighted problem and
  // renews the weights from its residuals, which for a loss concave in r^2
  // (Huber, Cauchy) never increases the robust objective (a majorise-
  // minimise step). It ends when a round moves no marker by more than the
  // tolerance.
  for (int round = 0; round < options.max_iterations; ++round) {
    const ExpressionProjection projection(b_used, w, options.ridge);
    const Rigid3 before = t;
    if (!solve_weighted(projection)) return out;
    Eigen::VectorXd d, c, r;
    evaluate(projection, &d, &c, &r);
    out.iterations = round + 1;
    out.last_step_mm = FurthestMoveMm(before, t, a_used);
    out.shape_weights = num_shapes > 0 ? c : out.shape_weights;
    for (int i = 0; i < n; ++i) {
      out.weights[used[i]] = w[i];
      out.residuals_mm[used[i]] = r[i];
    }
    out.converged = (round > 0 && out.last_step_mm <= options.tolerance_mm) ||
                    !robust;  // without a robust loss the weights are the prior's: one round
    if (out.converged || round + 1 == options.max_iterations) {
      const Eigen::Matrix3Xd p = t * a_used;
      Eigen::MatrixXd jac(3 * n, 6);
      for (int i = 0; i < n; ++i) {
        jac.block<3, 3>(3 * i, 0) = -Skew(p.col(i));
        jac.block<3, 3>(3 * i, 3).setIdentity();
      }
      // The estimate is delta = -H^-1 (QJ)^T d: for independent noise of
      // unit variance per coordinate its covariance is H^-1 (QJ)^T QJ H^-1
      // (the weights are not the noise's inverse variances).
      const Eigen::MatrixXd qj = projection.Apply(jac);
      const Eigen::Matrix<double, 6, 6> h = jac.transpose() * qj;
      const Eigen::Matrix<double, 6, 6> m = qj.transpose() * qj;
      out.information = h * m.ldlt().solve(h);
      break;
    }
    w = robust_weights(r);
  }
  out.ok = true;
  out.head_from_helmet = t;
  return out;
}

Mat3 Skew(const Vec3& v) {
  Mat3 m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

}  // namespace hmc
