#include "core/jaw.h"

#include <cmath>

#include "core/error.h"
#include "core/parallel.h"

namespace hmc {

const std::array<std::string, 3>& JawPose::ParameterNames() {
  static const std::array<std::string, 3> names = {"open_deg", "lateral_deg",
                                                   "protrude_mm"};
  return names;
}

JawPose JawPose::FromArray(const std::array<double, 3>& values) {
  JawPose pose;
  pose.open_deg = values[0];
  pose.lateral_deg = values[1];
  pose.protrude_mm = values[2];
  return pose;
}

Rigid3 JawRig::Transform(const JawPose& pose) const {
  constexpr double kDegToRad = M_PI / 180.0;
  const Mat3 rotation =
      (Eigen::AngleAxisd(pose.lateral_deg * kDegToRad, axes.col(1)) *
       Eigen::AngleAxisd(pose.open_deg * kDegToRad, axes.col(0)))
          .toRotationMatrix();
  Rigid3 head_from_jaw_rest = Rigid3::Identity();
  head_from_jaw_rest.linear() = rotation;
  head_from_jaw_rest.translation() =
      pivot - rotation * pivot + pose.protrude_mm * axes.col(2);
  return head_from_jaw_rest;
}

Vec3 SkinPoint(const JawRig& rig, const JawPose& pose, const Vec3& x,
               double w) {
  return SkinPoint(rig.Transform(pose), x, w);
}

Vec3 UnskinPoint(const JawRig& rig, const JawPose& pose, const Vec3& x,
                 double w) {
  const Rigid3 t = rig.Transform(pose);
  const Mat3 a = (1.0 - w) * Mat3::Identity() + w * t.linear();
  return a.partialPivLu().solve(x - w * t.translation());
}

namespace {

template <bool kInverse>
MatX3d SkinAll(const JawRig& rig, const JawPose& pose, const MatX3d& X) {
  HMC_CHECK(rig.weights.size() == X.rows());
  const Rigid3 t = rig.Transform(pose);
  MatX3d out(X.rows(), 3);
  ParallelFor(
      0, X.rows(),
      [&](int64_t v) {
        const double w = rig.weights[v];
        const Vec3 x = X.row(v).transpose();
        if (kInverse) {
          const Mat3 a = (1.0 - w) * Mat3::Identity() + w * t.linear();
          out.row(v) = a.partialPivLu().solve(x - w * t.translation());
        } else {
          out.row(v) = SkinPoint(t, x, w).transpose();
        }
      },
      1024);
  return out;
}

}  // namespace

MatX3d Skin(const JawRig& rig, const JawPose& pose, const MatX3d& X) {
  return SkinAll<false>(rig, pose, X);
}

MatX3d Unskin(const JawRig& rig, const JawPose& pose, const MatX3d& X) {
  return SkinAll<true>(rig, pose, X);
}

}  // namespace hmc
