// What the actor's package says about each marker, as stabilization and the
// jaw fit need it: where the marker sits on the neutral, how far each
// dataset shape moves it (skinned, as bundles see it, and unskinned by the
// shape's own jaw pose, as the jaw fit models the skin), and its jaw
// skinning at the surface point. Computed once per actor.
//
// Skinning a marker (the bundle model of indexing/shape_data.h, written
// here again because stabilization sits below indexing): the surface point
// s_k of the per-vertex skinned triangle whose unskinned corners are the
// neutral's moved by a common u - x0(s_k) is
//   S_k(u) = A(w_k) u + w_k t + (R - I) m_k,  A(w) = (1 - w) I + w R,
// with T(theta) = (R, t) the jaw transform (core/jaw.h), w_k the jaw
// weight interpolated at the surface point and m_k = sum_i b_i w_i
// (x0_i - x0(s_k)) the jaw moment over the triangle's corners i.
#pragma once

#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include <Eigen/Core>

#include "core/actor.h"

namespace hmc {

struct MarkerModel {
  int num_markers = 0;  // K
  int num_shapes = 0;   // N
  std::vector<std::string> names;                 // K
  std::unordered_map<std::string, int> index;     // name -> k
  MatX3d neutral;                // K x 3: x0(s_k), the marker on the neutral (mm)
  // 3K x N: rows 3k..3k+2 column n = shape n's displacement of marker k as
  // the bundle sees it (skinned: the shape's positions), d_kn (mm).
  Eigen::MatrixXd displacement;
  // 3K x N: the same unskinned by shape n's jaw pose, c*_kn - x0(s_k) (mm);
  // equal to `displacement` without a jaw rig.
  Eigen::MatrixXd unskinned_displacement;
  Eigen::VectorXd motion_rms;    // K: sqrt(mean_n |d_kn|^2) (mm)
  std::vector<char> stable;      // K: tagged `stable`
  std::vector<char> jaw;         // K: tagged `jaw`
  std::optional<JawRig> jaw_rig;
  Eigen::VectorXd jaw_weight;    // K: w_k (zero without a jaw rig)
  MatX3d jaw_moment;             // K x 3: m_k (mm)

  int Find(const std::string& name) const {
    const auto it = index.find(name);
    return it == index.end() ? -1 : it->second;
  }
  // S_k(u) for the jaw transform T (above).
  Vec3 Skin(int k, const Rigid3& t, const Vec3& u) const;
  // Its exact inverse: the head-space bundle p of marker k unskinned.
  Vec3 Unskin(int k, const Rigid3& t, const Vec3& p) const;
};

// Parallel over shapes.
MarkerModel ComputeMarkerModel(const Actor& actor);

// The normal matrix `normal` (N x N, sum over all K markers of
// B_k^T B_k plus a ridge) with the terms of the markers k where !used[k]
// taken out; b: 3K x N, rows 3k..3k+2 = B_k.
Eigen::MatrixXd NormalWithout(const Eigen::MatrixXd& normal, const Eigen::MatrixXd& b,
                              const std::vector<char>& used);

}  // namespace hmc
