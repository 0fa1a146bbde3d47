// The dataset as the index and the solve see it (docs/ARCHITECTURE.md, "Method steps", steps
// 1 and 8): shapes unskinned by their own jaw pose, b*_n = T(theta_n)^-1
// (x0 + b_n) - x0 (paper, "Jaw Articulation"), both per vertex (for the
// blend) and at every bundle's surface point (for the point clouds and the
// neighbour criterion).
//
// The point at a bundle is computed with exactly the operation that unskins
// an observed bundle (UnskinBundle): evaluate the surface point on the skinned
// shape, then unskin it with the jaw weight interpolated at the surface
// point. A bundle taken from a dataset shape therefore lands exactly on a
// cloud point.
#pragma once

#include <algorithm>
#include <optional>
#include <string>
#include <vector>

#include "core/actor.h"

namespace hmc {

struct ShapeData {
  int num_vertices = 0;
  int num_shapes = 0;
  int num_bundles = 0;
  std::vector<std::string> shape_names;   // N
  std::vector<std::string> bundle_names;  // K (the actor's markers)
  std::vector<SurfacePoint> sites;        // K bundle surface points
  Eigen::VectorXd site_jaw_weight;        // K skinning weights at the sites
  // K x 3 jaw moments m_k = sum_i bary_i w_i (x0_i - x0(s_k)) over the
  // site's triangle corners i: how the corners' different skinning weights
  // move the surface point beyond skinning it with the interpolated weight.
  MatX3d site_jaw_moment;
  MatX3d site_neutral;                    // K x 3 x0(s_k) (mm)
  // (N K) x 3: row n K + k = unskinned displacement of shape n at bundle k,
  // c*_{k,n} - x0(s_k) (mm).
  MatX3d site_displacement;
  // The per-vertex displacements b*_n(v) (mm) of the shapes that move each
  // vertex (b*_n(v) != 0; most shapes are local, so a blend need not visit
  // the others), CSR over vertices: shapes ascending in
  // vertex_shapes[vertex_shape_start[v] .. vertex_shape_start[v + 1]), and
  // 3 floats per entry in vertex_shape_displacement. One vertex's moving
  // shapes are one contiguous run, which is what the blend loops read (~13
  // of 108 shapes per vertex on the default actor).
  std::vector<int> vertex_shape_start;  // V + 1
  std::vector<int> vertex_shapes;
  std::vector<float> vertex_shape_displacement;
  std::optional<JawRig> jaw_rig;

  Vec3 SiteDisplacement(int shape, int bundle) const {
    return site_displacement.row(static_cast<int64_t>(shape) * num_bundles +
                                 bundle)
        .transpose();
  }
  // b*_n(v) (3 floats), or nullptr when shape n does not move vertex v.
  const float* Displacement(int v, int n) const {
    const int* first = vertex_shapes.data() + vertex_shape_start[v];
    const int* last = vertex_shapes.data() + vertex_shape_start[v + 1];
    const int* it = std::lower_bound(first, last, n);
    if (it == last || *it != n) return nullptr;
    return vertex_shape_displacement.data() + 3 * (it - vertex_shapes.data());
  }
};

// Parallel over shapes and vertices.
ShapeData ComputeShapeData(const Actor& actor);

// Skinning of bundle k's surface point: the surface point of the per-vertex
// skinned triangle whose unskinned shape is the neutral's triangle moved to
// u,
//   S_k(u) = A(w_k) u + w_k t + (R - I) m_k,  A(w) = (1 - w) I + w R,
// with T(theta) = (R, t), w_k the interpolated weight and m_k the jaw moment.
// Exact for the neutral and rigid translations of its triangle, so a pure jaw
// motion of the neutral unskins exactly to the neutral; identity without a
// jaw rig.
Vec3 SkinBundle(const ShapeData& data, int bundle, const JawPose& pose,
                const Vec3& u);
// Its exact inverse: the observed bundle k at p (head space) unskinned with
// the frame's jaw pose.
Vec3 UnskinBundle(const ShapeData& data, int bundle, const JawPose& pose,
                  const Vec3& p);

}  // namespace hmc
