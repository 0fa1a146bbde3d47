// The temporal prior on the head pose (docs/stabilization.md, "The temporal
// prior").
//
// Each frame's fit measures its pose T_f with information Lambda_f =
// H_f / sigma_f^2: H_f = J^T Q J of the joint fit (stabilization/head_fit.h,
// the expression projected out) and sigma_f^2 the frame's weighted residual
// variance per coordinate. A frame whose markers the dataset explains (the
// usual case) has a tiny sigma_f and keeps its pose; a frame with motion the
// dataset cannot explain (a unit it lacks, a bad track) leaves residuals, so
// its pose is known less well, and the neighbouring frames' poses inform it.
// The pose moves between frames as a random walk, increments of covariance
// Sigma_p per frame, so the maximum a posteriori trajectory minimises
//   sum_f d_f^T Lambda_f d_f + sum_f (u_f + d_g - d_f)^T (gap Sigma_p)^-1 (...)
// over left perturbations d_f = (omega, v) of the fitted poses (head-space
// points p -> p + omega x p + v), u_f the increment between consecutive
// frames f, g; a linear least-squares problem with a block-tridiagonal
// matrix, relinearised until its step is below the tolerance. Sigma_p is
// estimated from the shot by the method of moments: per parameter, the
// median squared increment (over its median for a chi-square of one degree,
// so that a few large increments do not inflate it) less the two frames'
// measurement variances. Slip and vibration that the markers show stay in
// the increments, and so in Sigma_p: the prior only decides between
// frames in proportion to how well each determines its own pose.
#pragma once

#include <vector>

#include <Eigen/Core>

#include "core/types.h"

namespace hmc {

struct PoseMeasurement {
  int frame = 0;               // frame number (gaps scale the random walk)
  Rigid3 pose = Rigid3::Identity();  // fitted, or interpolated where !ok
  bool ok = false;             // false: no measurement (the prior alone places it)
  Eigen::Matrix<double, 6, 6> information = Eigen::Matrix<double, 6, 6>::Zero();  // H_f
  double variance_mm2 = 0;     // sigma_f^2 (floored by the caller)
};

// Poses of every frame (one per measurement) under the temporal prior; fewer than 3 measured
// frames: the poses as given. `tolerance_mm`: relinearise until a step moves
// no point at `lever_mm` from `center` further.
// `center`, `lever_mm`: the perturbations are parameterised as rotations
// about `center` (the markers' centroid, where rotation and translation
// are least correlated), scaled by `lever_mm` (their RMS distance from it).
std::vector<Rigid3> SmoothPoseTrajectory(const std::vector<PoseMeasurement>& measurements,
                                         double tolerance_mm, const Vec3& center,
                                         double lever_mm);

}  // namespace hmc
