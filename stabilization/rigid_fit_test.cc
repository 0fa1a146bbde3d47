#include "stabilization/rigid_fit.h"

#include <random>

#include <gtest/gtest.h>

#include "stabilization/shot_test_util.h"

namespace hmc {
namespace {

class RigidFitSeeded : public ::testing::TestWithParam<unsigned> {};

TEST_P(RigidFitSeeded, RecoversAnExactRigidMotionWhateverTheWeights) {
  std::mt19937 rng(GetParam());
  std::normal_distribution<double> normal(0, 40);
  std::uniform_real_distribution<double> weight(0.001, 1);
  const int n = 5 + GetParam() % 20;
  const Rigid3 truth = RandomRigid(rng, 3.0 * 180 / M_PI, 50);
  Eigen::Matrix3Xd a(3, n), b(3, n);
  Eigen::VectorXd w(n);
  for (int i = 0; i < n; ++i) {
    a.col(i) = Vec3(normal(rng), normal(rng), normal(rng));
    b.col(i) = truth * Vec3(a.col(i));
    w[i] = weight(rng);
  }
  const RigidFit fit = WeightedRigidFit(a, b, w);
  ASSERT_TRUE(fit.ok);
  EXPECT_LT((fit.target_from_source.matrix() - truth.matrix()).norm(), 1e-10);
  EXPECT_NEAR(fit.target_from_source.linear().determinant(), 1.0, 1e-12);
}

TEST_P(RigidFitSeeded, MinimisesTheWeightedSquaredResidual) {
  // With noisy targets, no small perturbation of the fit lowers E(R, t).
  std::mt19937 rng(GetParam());
  std::normal_distribution<double> normal(0, 30), noise(0, 0.5);
  std::uniform_real_distribution<double> weight(0.01, 1);
  const int n = 12;
  Eigen::Matrix3Xd a(3, n), b(3, n);
  Eigen::VectorXd w(n);
  const Rigid3 truth = RandomRigid(rng, 1.0 * 180 / M_PI, 20);
  for (int i = 0; i < n; ++i) {
    a.col(i) = Vec3(normal(rng), normal(rng), normal(rng));
    b.col(i) = truth * Vec3(a.col(i)) + Vec3(noise(rng), noise(rng), noise(rng));
    w[i] = weight(rng);
  }
  const RigidFit fit = WeightedRigidFit(a, b, w);
  ASSERT_TRUE(fit.ok);
  auto energy = [&](const Rigid3& t) {
    return ((t * a - b).colwise().squaredNorm().transpose().array() * w.array()).sum();
  };
  const double best = energy(fit.target_from_source);
  for (int trial = 0; trial < 50; ++trial) {
    const Rigid3 perturbed = RandomRigid(rng, 1e-3 * 180 / M_PI, 1e-2) * fit.target_from_source;
    EXPECT_GE(energy(perturbed), best - 1e-9);
  }
}

INSTANTIATE_TEST_SUITE_P(Seeds, RigidFitSeeded, ::testing::Values(1u, 2u, 3u, 7u, 11u));

TEST(RigidFitTest, RefusesTooFewOrCollinearPoints) {
  Eigen::Matrix3Xd a(3, 4);
  a << 0, 1, 2, 3, 0, 2, 4, 6, 0, 0, 0, 0;  // on one line
  const Eigen::VectorXd w = Eigen::VectorXd::Ones(4);
  EXPECT_FALSE(WeightedRigidFit(a, a, w).ok);
  a(2, 3) = 1;  // off the line
  EXPECT_TRUE(WeightedRigidFit(a, a, w).ok);
  Eigen::VectorXd two = Eigen::VectorXd::Zero(4);
  two[0] = two[3] = 1;
  EXPECT_FALSE(WeightedRigidFit(a, a, two).ok);
}

TEST(RigidFitTest, RobustWeightsFollowTheirLosses) {
  EXPECT_EQ(RobustWeight(RobustLoss::kNone, 7, 1), 1);
  EXPECT_EQ(RobustWeight(RobustLoss::kHuber, 0.5, 1), 1);
  EXPECT_DOUBLE_EQ(RobustWeight(RobustLoss::kHuber, 4, 1), 0.25);
  EXPECT_DOUBLE_EQ(RobustWeight(RobustLoss::kCauchy, 2, 1), 0.2);
  RobustLoss loss;
  EXPECT_TRUE(ParseRobustLoss("huber", &loss));
  EXPECT_EQ(loss, RobustLoss::kHuber);
  EXPECT_FALSE(ParseRobustLoss("tukey", &loss));
}

}  // namespace
}  // namespace hmc
