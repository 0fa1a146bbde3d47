#include "core/jaw.h"

#include <random>

#include <gtest/gtest.h>

namespace hmc {
namespace {

JawRig RandomRig(std::mt19937& rng, int num_vertices) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  JawRig rig;
  rig.pivot = Vec3(unit(rng) * 10 - 5, 20 + unit(rng) * 10, -60 - unit(rng) * 20);
  // A slightly tilted but orthonormal, right-handed frame.
  rig.axes = Eigen::AngleAxisd(0.2 * (unit(rng) - 0.5), Vec3::UnitZ()) *
             Eigen::AngleAxisd(0.2 * (unit(rng) - 0.5), Vec3::UnitY())
                 .toRotationMatrix();
  rig.weights = Eigen::VectorXd(num_vertices);
  for (int v = 0; v < num_vertices; ++v) rig.weights[v] = unit(rng);
  rig.weights[0] = 0.0;
  rig.weights[1] = 1.0;
  return rig;
}

class JawTest : public ::testing::TestWithParam<int> {};

TEST_P(JawTest, UnskinInvertsSkin) {
  std::mt19937 rng(GetParam());
  std::uniform_real_distribution<double> coord(-80.0, 80.0);
  const int n = 200;
  const JawRig rig = RandomRig(rng, n);
  MatX3d x(n, 3);
  for (int v = 0; v < n; ++v) x.row(v) = Vec3(coord(rng), coord(rng), coord(rng));
  std::uniform_real_distribution<double> angle(-30.0, 30.0);
  const JawPose pose{angle(rng), angle(rng) / 4, angle(rng) / 6};
  const MatX3d round_trip = Unskin(rig, pose, Skin(rig, pose, x));
  EXPECT_LT((round_trip - x).cwiseAbs().maxCoeff(), 1e-10);
  for (int v = 0; v < n; ++v) {
    const Vec3 p = x.row(v).transpose();
    const double w = rig.weights[v];
    EXPECT_LT((UnskinPoint(rig, pose, SkinPoint(rig, pose, p, w), w) - p).norm(),
              1e-10);
  }
}

TEST_P(JawTest, FullWeightIsRigidAboutPivot) {
  std::mt19937 rng(GetParam());
  const JawRig rig = RandomRig(rng, 2);
  const JawPose pose{22.0, 0.0, 0.0};
  // Offset perpendicular to the hinge, so the swept angle equals open_deg.
  const Vec3 chin = rig.pivot + rig.axes * Vec3(0, -70, 90);
  const Vec3 moved = SkinPoint(rig, pose, chin, 1.0);
  // Pure opening: distance to the pivot is kept, the pivot does not move,
  // and the chin moves down.
  EXPECT_NEAR((moved - rig.pivot).norm(), (chin - rig.pivot).norm(), 1e-9);
  EXPECT_LT((SkinPoint(rig, pose, rig.pivot, 1.0) - rig.pivot).norm(), 1e-9);
  EXPECT_LT(moved.dot(rig.axes.col(1)), chin.dot(rig.axes.col(1)));
  // Zero weight never moves.
  EXPECT_EQ(SkinPoint(rig, pose, chin, 0.0), chin);
  // The opening angle is what the pose says.
  const Vec3 a = (chin - rig.pivot).normalized();
  const Vec3 b = (moved - rig.pivot).normalized();
  EXPECT_NEAR(std::acos(std::clamp(a.dot(b), -1.0, 1.0)) * 180 / M_PI, 22.0,
              1e-9);
}

TEST(JawPoseTest, ArrayRoundTripAndNames) {
  const JawPose pose{1.5, -2.0, 3.25};
  const JawPose back = JawPose::FromArray(pose.ToArray());
  EXPECT_EQ(back.open_deg, 1.5);
  EXPECT_EQ(back.lateral_deg, -2.0);
  EXPECT_EQ(back.protrude_mm, 3.25);
  EXPECT_EQ(JawPose::ParameterNames()[0], "open_deg");
  EXPECT_FALSE(pose.IsZero());
  EXPECT_TRUE(JawPose().IsZero());
}

INSTANTIATE_TEST_SUITE_P(Seeds, JawTest, ::testing::Values(1, 2, 3, 17));

}  // namespace
}  // namespace hmc
