#include "stabilization/rigid_fit.h"

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>

namespace hmc {

RigidFit WeightedRigidFit(const Eigen::Matrix3Xd& a, const Eigen::Matrix3Xd& b,
                          const Eigen::VectorXd& w) {
  RigidFit fit;
  int positive = 0;
  for (int i = 0; i < w.size(); ++i) positive += w[i] > 0;
  const double total = w.sum();
  if (positive < 3 || !(total > 0)) return fit;
  const Vec3 a_bar = a * w / total;
  const Vec3 b_bar = b * w / total;
  const Eigen::Matrix3Xd a_centred = a.colwise() - a_bar;
  const Eigen::Matrix3Xd b_centred = b.colwise() - b_bar;
  const Mat3 h = a_centred * w.asDiagonal() * b_centred.transpose();
  // Collinear (or coincident) source points leave a rotation about their
  // line free: the source spread's second principal value must be positive.
  const Mat3 spread = a_centred * w.asDiagonal() * a_centred.transpose();
  const Eigen::Vector3d spread_values =
      Eigen::SelfAdjointEigenSolver<Mat3>(spread, Eigen::EigenvaluesOnly)
          .eigenvalues();
  if (!(spread_values[1] > 1e-9 * spread_values[2])) return fit;
  const Eigen::JacobiSVD<Mat3> svd(h, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Mat3 d = Mat3::Identity();
  d(2, 2) = (svd.matrixV() * svd.matrixU().transpose()).determinant() < 0 ? -1 : 1;
  const Mat3 r = svd.matrixV() * d * svd.matrixU().transpose();
  fit.target_from_source.linear() = r;
  fit.target_from_source.translation() = b_bar - r * a_bar;
  fit.ok = true;
  return fit;
}

bool ParseRobustLoss(const std::string& name, RobustLoss* loss) {
  if (name == "none") {
    *loss = RobustLoss::kNone;
  } else if (name == "huber") {
    *loss = RobustLoss::kHuber;
  } else if (name == "cauchy") {
    *loss = RobustLoss::kCauchy;
  } else {
    return false;
  }
  return true;
}

double RobustWeight(RobustLoss loss, double r, double c) {
  switch (loss) {
    case RobustLoss::kHuber:
      return r <= c ? 1.0 : c / r;
    case RobustLoss::kCauchy:
      return 1.0 / (1.0 + (r / c) * (r / c));
    case RobustLoss::kNone:
      break;
  }
  return 1.0;
}

}  // namespace hmc
