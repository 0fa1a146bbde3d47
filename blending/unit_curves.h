// Animation curves out (docs/method.md, "Animation curves"): the actor's
// units as a blendshape rig, a fit of the rig to each solved mesh, and the
// files a DCC reads (weights.csv, curves.csv, a .usda BlendShape rig with
// time-sampled weights; docs/formats.md, "Unit weights and curves").
//
// Units. The solve's weights are over the dataset's shapes, per bundle;
// an animator's controls are the actor's units. A shape whose name holds
// "__" is a combination (a corrective of the units it joins) and not a
// unit; a name ending in "_NNN" (three digits) is the unit before it at
// NNN % (an in-between, or the extreme at 100); any other name is a unit
// at 100 %. Each unit's blendshape is its highest-activation shape,
// unskinned by that shape's own jaw pose (indexing/shape_data.h) and
// scaled to 100 %: d_u = b*_n / a_n.
//
// The rig: x(w, theta) = T(theta)(x0 + sum_u w_u d_u), the jaw skinned per
// vertex as the solve skins it (core/jaw.h), theta the frame's jaw pose.
//
// The fit: per frame, the solved mesh X is unskinned with the frame's jaw
// pose, and w = argmin |sum_u w_u d_u - (T^-1 X - x0)|^2 over every vertex,
// 0 <= w_u <= 1 (projected coordinate descent on the U x U normal
// equations, to convergence). Where the solved mesh is in the span of the
// units the rig reproduces it; elsewhere (in-betweens the generator makes
// nonlinear, combinations, expressions the dataset lacks) the fit's
// residual says by how much it does not.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "core/actor.h"
#include "core/jaw.h"
#include "core/types.h"

namespace hmc {

struct UnitRig {
  std::vector<std::string> names;      // U units, in the actor's shape order
  std::vector<int> shape;              // the dataset shape of each
  std::vector<double> activation;      // that shape's activation (1 = 100 %)
  std::vector<MatX3d> displacement;    // U, each V x 3: d_u (mm)
};

// Throws InputError naming the actor when it has no unit (no shape that is
// not a combination).
UnitRig UnitRigFromActor(const Actor& actor);

// x(w, theta) (V x 3, mm). w: U weights.
MatX3d EvaluateUnitRig(const UnitRig& rig, const Actor& actor, const Eigen::VectorXd& w,
                       const JawPose& jaw);

struct UnitFit {
  std::vector<Eigen::VectorXd> weights;  // per frame, U weights in [0, 1]
  std::vector<double> mean_mm;           // per frame: mean over the vertices
                                         // of |x(w, theta) - X|
  double mean_mm_all = 0.0;              // over every frame and vertex
  double max_frame_mean_mm = 0.0;
  // Sets the last two from mean_mm.
  void Summarize();
};

// The fit of one mesh at a time (FitUnitWeights fits every frame with it),
// for a solve that hands its meshes over as they come: the units' Gram
// matrix is computed once. rig and actor must outlive it.
class UnitFitter {
 public:
  UnitFitter(const UnitRig& rig, const Actor& actor);
  // Fits the weights (U, in [0, 1]) of `mesh` (V x 3) with the frame's jaw
  // pose; returns the mean over the vertices of |x(w, theta) - mesh| (mm).
  double Fit(const MatX3d& mesh, const JawPose& pose, Eigen::VectorXd* weights) const;

 private:
  const UnitRig& rig_;
  const Actor& actor_;
  Eigen::MatrixXd G_;  // U x U: sum over vertices of d_u . d_v
};

// meshes: the solved meshes; jaw: one pose per mesh, or empty (zero pose).
UnitFit FitUnitWeights(const UnitRig& rig, const Actor& actor, const std::vector<MatX3d>& meshes,
                       const std::vector<JawPose>& jaw);

// The channels written: the units, then (with a jaw rig) jaw_open_deg,
// jaw_lateral_deg, jaw_protrude_mm.
struct UnitAnimation {
  std::vector<std::string> channels;
  int start_frame = 1;
  double fps = 30.0;
  std::vector<std::vector<double>> values;  // per frame, one per channel
};
UnitAnimation MakeUnitAnimation(const UnitRig& rig, const Actor& actor, const UnitFit& fit,
                                const std::vector<JawPose>& jaw, int start_frame, double fps);

// weights.csv: frame,<channel>... one row per frame. Atomic.
void WriteUnitWeightsCsv(const std::filesystem::path& path, const UnitAnimation& animation);
// curves.csv: channel,frame,time_s,value, one block of rows per channel
// (linear keys at every frame). Atomic.
void WriteUnitCurvesCsv(const std::filesystem::path& path, const UnitAnimation& animation);
// A USD ASCII stage: the neutral as a skinned Mesh with one BlendShape per
// unit, a Skeleton (root and, with a jaw rig, the jaw joint and its
// per-vertex weights) and a SkelAnimation with the units' weights (and the
// jaw joint's transform) time-sampled at frame numbers. Atomic.
void WriteUnitRigUsda(const std::filesystem::path& path, const UnitRig& rig, const Actor& actor,
                      const UnitAnimation& animation, const std::vector<JawPose>& jaw);

}  // namespace hmc
