#include "indexing/shape_data.h"

#include <array>

#include "core/parallel.h"

namespace hmc {

ShapeData ComputeShapeData(const Actor& actor) {
  ShapeData d;
  const TriMesh& mesh = actor.neutral;
  d.num_vertices = mesh.NumVertices();
  d.num_shapes = static_cast<int>(actor.shapes.size());
  d.num_bundles = static_cast<int>(actor.markers.size());
  d.jaw_rig = actor.jaw_rig;
  const int V = d.num_vertices, N = d.num_shapes, K = d.num_bundles;
  for (const auto& s : actor.shapes) d.shape_names.push_back(s.name);
  d.site_jaw_weight = Eigen::VectorXd::Zero(K);
  d.site_neutral.resize(K, 3);
  d.site_jaw_moment = MatX3d::Zero(K, 3);
  for (int k = 0; k < K; ++k) {
    const Marker& m = actor.markers[k];
    d.bundle_names.push_back(m.name);
    d.sites.push_back(m.point);
    d.site_neutral.row(k) =
        EvaluateSurfacePoint(m.point, mesh.F, mesh.V).transpose();
    if (d.jaw_rig) {
      double w = 0;
      for (int i = 0; i < 3; ++i) {
        w += m.point.bary[i] * d.jaw_rig->weights[mesh.F(m.point.face, i)];
      }
      d.site_jaw_weight[k] = w;
      for (int i = 0; i < 3; ++i) {
        const int v = mesh.F(m.point.face, i);
        d.site_jaw_moment.row(k) += m.point.bary[i] * d.jaw_rig->weights[v] *
                                    (mesh.V.row(v) - d.site_neutral.row(k));
      }
    }
  }
  d.site_displacement.resize(static_cast<int64_t>(N) * K, 3);
  // Per shape, the vertices it moves and by how much; then transposed to
  // the per-vertex runs (shapes ascending).
  struct Moved {
    int vertex;
    std::array<float, 3> displacement;
  };
  std::vector<std::vector<Moved>> moved(N);
  ParallelFor(0, N, [&](int64_t n) {
    const Shape& shape = actor.shapes[n];
    MatX3d unskinned = mesh.V + shape.displacement;
    for (int k = 0; k < K; ++k) {
      const Vec3 on_shape =
          EvaluateSurfacePoint(d.sites[k], mesh.F, unskinned);
      const Vec3 c = UnskinBundle(d, k, shape.jaw, on_shape);
      d.site_displacement.row(n * K + k) =
          (c - d.site_neutral.row(k).transpose()).transpose();
    }
    if (d.jaw_rig) unskinned = Unskin(*d.jaw_rig, shape.jaw, unskinned);
    for (int v = 0; v < V; ++v) {
      Moved m{v, {}};
      for (int a = 0; a < 3; ++a) {
        m.displacement[a] = static_cast<float>(unskinned(v, a) - mesh.V(v, a));
      }
      if (m.displacement != std::array<float, 3>{0.0f, 0.0f, 0.0f}) {
        moved[n].push_back(m);
      }
    }
  });
  d.vertex_shape_start.assign(V + 1, 0);
  for (const auto& list : moved) {
    for (const Moved& m : list) ++d.vertex_shape_start[m.vertex + 1];
  }
  for (int v = 0; v < V; ++v) {
    d.vertex_shape_start[v + 1] += d.vertex_shape_start[v];
  }
  d.vertex_shapes.resize(d.vertex_shape_start[V]);
  d.vertex_shape_displacement.resize(3 * static_cast<size_t>(d.vertex_shape_start[V]));
  std::vector<int> fill(d.vertex_shape_start.begin(), d.vertex_shape_start.end() - 1);
  for (int n = 0; n < N; ++n) {
    for (const Moved& m : moved[n]) {
      const int j = fill[m.vertex]++;
      d.vertex_shapes[j] = n;
      std::copy(m.displacement.begin(), m.displacement.end(),
                d.vertex_shape_displacement.begin() + 3 * j);
    }
  }
  return d;
}

namespace {

// The terms of S_k (shape_data.h) for bundle k under `pose`: T(theta), the
// interpolated weight w_k and the jaw moment m_k. Needs a jaw rig.
struct BundleSkinning {
  Rigid3 t;
  double w;
  Vec3 m;
};
BundleSkinning SkinningOf(const ShapeData& data, int bundle,
                          const JawPose& pose) {
  return {data.jaw_rig->Transform(pose), data.site_jaw_weight[bundle],
          data.site_jaw_moment.row(bundle).transpose()};
}

}  // namespace

Vec3 SkinBundle(const ShapeData& data, int bundle, const JawPose& pose,
                const Vec3& u) {
  if (!data.jaw_rig) return u;
  const auto [t, w, m] = SkinningOf(data, bundle, pose);
  return (1.0 - w) * u + w * (t * u) + (t.linear() * m - m);
}

Vec3 UnskinBundle(const ShapeData& data, int bundle, const JawPose& pose,
                  const Vec3& p) {
  if (!data.jaw_rig) return p;
  const auto [t, w, m] = SkinningOf(data, bundle, pose);
  const Mat3 a = (1.0 - w) * Mat3::Identity() + w * t.linear();
  return a.partialPivLu().solve(p - w * t.translation() -
                                (t.linear() * m - m));
}

}  // namespace hmc
