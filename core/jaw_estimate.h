// A jaw rig estimated from an actor's dataset, for an actor whose package
// has none (docs/formats.md, "An estimated jaw rig"): the dataset's jaw
// shapes, found by name (a jaw open or drop; a jaw left or sideways; a jaw
// forward or thrust), move the lower jaw's vertices by a rigid motion
// blended with per-vertex weights, x' = (1 - w) x + w T x (core/jaw.h).
//
// - Hinge and pivot, the open angle and the weights from the jaw-open
//   shape: with d_k its displacement of vertex k,
//     min_{R, p} sum_k |d_k - w_k (R - I)(x_k - p)|^2,
//   w_k = clamp(d_k . u_k / |u_k|^2, 0, 1), u_k = (R - I)(x_k - p), R a
//   rotation about an axis through p, over the vertices it moves (the
//   weights projected out; started from the axis the displacements are
//   perpendicular to and the pivot whose chords they are). The hinge is
//   R's axis, signed so that the shape opens the mouth; the pivot lies on
//   it, at the moving vertices' centroid along it.
// - The vertical axis from the sideways shape's rotation fitted likewise
//   (with the weights and pivot fixed), made perpendicular to the hinge;
//   without one, head space's +y made perpendicular to the hinge. Forward =
//   hinge x vertical.
// - Every shape's jaw pose: the pose whose skinning best explains the
//   shape's displacement of the jaw-weighted vertices, kept where it
//   explains at least half of it (else zero: a shape that moves the chin's
//   skin without the bone).
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "core/actor.h"

namespace hmc {

struct JawRigEstimate {
  JawRig rig;
  std::vector<JawPose> shape_poses;   // per actor shape (zero where none)
  std::string open_shape;             // the shapes it was fitted to ("" = none)
  std::string lateral_shape;
  std::string forward_shape;
  double open_rms_mm = 0;             // RMS residual of the open fit over its vertices (mm)
  int shapes_with_pose = 0;
  std::string Describe() const;       // one line for `hmc actor check`
};

// The estimate, or nothing when the actor has no shape named as a jaw
// opening (or the fit degenerates). Does not look at actor.jaw_rig.
std::optional<JawRigEstimate> EstimateJawRig(const Actor& actor);

// Sets actor->jaw_rig and every shape's jaw pose from `estimate`.
void ApplyJawRigEstimate(const JawRigEstimate& estimate, Actor* actor);

}  // namespace hmc
