// The FACS-like action units of the synthetic actor (Ekman & Friesen, Facial
// Action Coding System, 1978: the unit numbers follow FACS; the deformations
// are procedural stand-ins, not measured muscle actions).
//
// The face's deformation is a sum of terms. Each term is a fixed vector field
// over the neutral vertices (smooth region-localised displacements, or fine
// detail along the neutral normal: wrinkles, folds, dimples, bulges) scaled
// by a coefficient that is a NONLINEAR function of the activations:
//  - smooth part of unit k: ease(a_k) = a_k (1.3 - 0.3 a_k),
//  - fine detail of unit k: a_k^2 or a smoothstep beyond a threshold, so it
//    is absent from the neutral and from small activations,
//  - interactions: products a_i a_j (smile x cheek raiser deepens crow's
//    feet; jaw drop x funneler rounds the lips; lip pressor x chin raiser
//    bulges the chin; pucker x funneler compete for the same tissue, ...).
// The summed displacement then saturates softly (FaceModel), and the jaw
// units set the jaw pose with which the result is skinned.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "core/jaw.h"
#include "core/types.h"
#include "synth/face_mesh.h"

namespace hmc {

struct ActionUnit {
  std::string name;               // "AU12_lip_corner_puller_L"
  std::vector<std::string> tags;  // region tags ("mouth", "cheek_l", ...)
  bool drives_jaw = false;        // contributes to the jaw pose
};

// What a term's field may depend on, per neutral vertex.
struct VertexContext {
  Vec2 st;              // face-plane coordinates (mm)
  Vec3 normal;          // unit outward normal of the neutral
  double jaw_weight;    // the vertex's jaw skinning weight
};

struct DeformationTerm {
  std::string label;  // for debugging: "AU12_L detail"
  std::function<double(const Eigen::VectorXd&)> coefficient;  // of a (K)
  std::function<Vec3(const VertexContext&)> field;            // mm at coeff 1
};

struct UnitCatalog {
  std::vector<ActionUnit> units;
  std::vector<DeformationTerm> terms;
  // The broad rig's artist-style region of each unit (mm at activation 1),
  // parallel to `units`; empty unless AddBroadRegions was called.
  std::vector<std::function<Vec3(const VertexContext&)>> broad;
  // Jaw pose from the K activations (jaw drop, mouth stretch, sideways,
  // thrust; opening saturates softly).
  std::function<JawPose(const Eigen::VectorXd&)> jaw_pose;

  int Find(const std::string& name) const;  // -1 if absent
};

// The catalog for a face with proportions `p`; `detail_scale` scales every
// fine-detail amplitude (1 = default).
UnitCatalog BuildUnitCatalog(const FaceProportions& p, double detail_scale);

// The broad rig (docs/synthetic.md, "Broad rig"): gives every unit of
// `catalog` a broad, overlapping region as artists' FACS shapes move them
// (a brow raise lifts the whole forehead to the hairline, a smile the cheek
// up to the lower lid, the jaw units and mouth left/right the whole lower
// face; squint, blink and jaw drop reach the temples, the brow lowerer and
// nose wrinkler the nose bridge), widens the units' region tags to match,
// and appends the units artists' rigs have that the generator lacks
// (mouth_left, mouth_right: no terms, only a broad region).
void AddBroadRegions(const FaceProportions& p, UnitCatalog* catalog);

}  // namespace hmc
