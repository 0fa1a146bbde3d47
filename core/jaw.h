// The jaw rig and linear blend skinning (paper, section "Jaw Articulation").
//
// The jaw is a rigid bone in head space: it rotates about a hinge through
// `pivot` (opening about the hinge axis, lateral swing about the vertical
// axis) and slides forward (protrusion). Each vertex follows it with weight
// w in [0,1]:  x' = (1 - w) x + w T(theta) x,  i.e. x' = A_w x + t_w with
// A_w = (1 - w) I + w R, which is invertible for w in [0,1] and rotations
// below 180 degrees, so unskinning is exact.
#pragma once

#include <array>
#include <string>

#include "core/types.h"

namespace hmc {

struct JawPose {
  double open_deg = 0.0;     // rotation about the hinge axis; + opens the mouth
  double lateral_deg = 0.0;  // swing about the vertical axis; + to actor's left
  double protrude_mm = 0.0;  // slide along the forward axis; + forward

  // Names as used in jaw.csv and actor.yaml, in this order.
  static const std::array<std::string, 3>& ParameterNames();
  std::array<double, 3> ToArray() const { return {open_deg, lateral_deg, protrude_mm}; }
  static JawPose FromArray(const std::array<double, 3>& values);
  bool IsZero() const { return open_deg == 0 && lateral_deg == 0 && protrude_mm == 0; }
};

struct JawRig {
  Vec3 pivot = Vec3::Zero();      // hinge centre in head space (mm)
  Mat3 axes = Mat3::Identity();   // columns: hinge (+x), vertical (+y),
                                  // forward (+z); orthonormal, right-handed
  Eigen::VectorXd weights;        // V skinning weights in [0,1]

  // head_from_jaw_rest: where a fully weighted point moves under `pose`.
  Rigid3 Transform(const JawPose& pose) const;
};

// Skins one point with weight w: (1 - w) x + w T x.
Vec3 SkinPoint(const JawRig& rig, const JawPose& pose, const Vec3& x, double w);
// The same with T = rig.Transform(pose) given (computed once for many
// points).
inline Vec3 SkinPoint(const Rigid3& t, const Vec3& x, double w) {
  return (1.0 - w) * x + w * (t * x);
}
// Exact inverse of SkinPoint for the same weight.
Vec3 UnskinPoint(const JawRig& rig, const JawPose& pose, const Vec3& x,
                 double w);

// Per-vertex skinning of all rows of X (V x 3) with rig.weights; parallel.
MatX3d Skin(const JawRig& rig, const JawPose& pose, const MatX3d& X);
MatX3d Unskin(const JawRig& rig, const JawPose& pose, const MatX3d& X);

}  // namespace hmc
