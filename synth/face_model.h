// The one evaluation function of the synthetic actor, shared by the dataset,
// the ground-truth frames and synthetic footage:
//
//   x(a) = Skin(rig, JawPoseOf(a), x0 + Saturate(sum_terms c_j(a) F_j))
//
// with the neutral x0, the action-unit terms (synth/action_units.h: fixed
// fields F_j, nonlinear coefficients c_j), a soft per-vertex saturation of
// the summed displacement, and linear blend skinning by the jaw rig
// (core/jaw.h). The fields are precomputed once, stored sparse per vertex,
// so one evaluation is a short gather per vertex (parallel over vertices).
//
// With SynthActorOptions::rig "linear" the model is instead a purely linear
// rig, the regime most production rigs live in (docs/synthetic.md, "Linear
// rig"): x(a) = x0 + sum_k a_k E_k, E_k = the generator's unit k alone at
// activation 1 (jaw skinning included) minus x0. No activation-dependent
// detail, no interactions, no saturation, no jaw rig (JawPoseOf is zero):
// in-betweens lie on the line and combinations are exactly sums.
//
// With rig "broad" the model is linear in the same way, but each unit's
// extreme E_k also carries the unit's broad, overlapping region as artists'
// FACS shapes move it (synth/action_units.h AddBroadRegions, docs/synthetic.md
// "Broad rig"), and the catalog has the two units artists' rigs add
// (mouth_left, mouth_right).
#pragma once

#include <string>
#include <vector>

#include "core/jaw.h"
#include "core/mesh.h"
#include "synth/action_units.h"
#include "synth/face_mesh.h"

namespace hmc {

struct SynthActorOptions;

class FaceModel {
 public:
  explicit FaceModel(const SynthActorOptions& options);

  const FaceMesh& face() const { return face_; }
  const TriMesh& neutral() const { return face_.mesh; }
  // The generator's jaw rig (the linear rig still builds its extremes with
  // it); has_jaw_rig() says whether evaluations are skinned with it.
  const JawRig& jaw_rig() const { return face_.jaw_rig; }
  bool has_jaw_rig() const { return !linear_; }
  bool linear() const { return linear_; }  // "linear" and "broad"
  bool broad() const { return broad_; }
  int NumVertices() const { return face_.mesh.NumVertices(); }

  int NumUnits() const { return static_cast<int>(catalog_.units.size()); }
  const std::vector<ActionUnit>& units() const { return catalog_.units; }
  int FindUnit(const std::string& name) const { return catalog_.Find(name); }
  Eigen::VectorXd ZeroActivations() const {
    return Eigen::VectorXd::Zero(NumUnits());
  }

  // a: K activations, clamped to [0, 1].
  JawPose JawPoseOf(const Eigen::VectorXd& a) const;
  // V x 3 positions before jaw skinning (mm).
  MatX3d EvaluateUnskinned(const Eigen::VectorXd& a) const;
  // V x 3 final positions (mm).
  MatX3d Evaluate(const Eigen::VectorXd& a) const;

  // Soft limit of a vertex's summed displacement length (mm): identity up
  // to kSaturationKnee, then approaching kSaturationLimit (tanh).
  static constexpr double kSaturationKnee = 10.0;
  static constexpr double kSaturationLimit = 20.0;
  static double Saturate(double length);

 private:
  MatX3d Displace(const Eigen::VectorXd& a) const;
  MatX3d DisplaceLinear(const Eigen::VectorXd& a) const;
  // The linear rig's extremes, sparse per vertex as the terms' fields:
  // entries [unit_offsets_[v], unit_offsets_[v+1]) of unit_ and unit_field_.
  void BuildLinearRig();
  VertexContext ContextOf(int64_t v, const MatX3d& normals) const;

  FaceMesh face_;
  UnitCatalog catalog_;
  // Sparse fields, per vertex: entries [offsets_[v], offsets_[v+1]) of
  // term_ (term index) and field_ (its displacement at coefficient 1).
  std::vector<int64_t> offsets_;
  std::vector<int> term_;
  std::vector<Vec3> field_;
  bool linear_ = false;
  bool broad_ = false;
  std::vector<int64_t> unit_offsets_;
  std::vector<int> unit_;
  std::vector<Vec3> unit_field_;
};

}  // namespace hmc
