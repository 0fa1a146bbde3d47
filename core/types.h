// Conventions, stated once for all of hmc:
//  - Units: millimetres and degrees unless a name says otherwise
//    (`_px` pixels, `_s` seconds, `_rad` radians, `_cm` centimetres).
//  - Rigid transforms are named `target_from_source`: a point in the source
//    frame maps to the target frame as x_in_target = target_from_source * x.
//  - Points are named `x_in_frame` (`p_in_head`, `c_in_cam`).
//  - Head space is the neutral mesh's space: +x to the actor's left, +y up,
//    +z forward out of the face (right-handed).
//  - Pixels follow OpenCV: the centre of the top-left pixel is (0, 0).
//  - Matrices of points are row-major N x 3 (one point per row).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace hmc {

using Vec2 = Eigen::Vector2d;
using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;
using Rigid3 = Eigen::Isometry3d;

using MatX3d = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;
using MatX2d = Eigen::Matrix<double, Eigen::Dynamic, 2, Eigen::RowMajor>;
using MatX3i = Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor>;
using MatX3f = Eigen::Matrix<float, Eigen::Dynamic, 3, Eigen::RowMajor>;

}  // namespace hmc
