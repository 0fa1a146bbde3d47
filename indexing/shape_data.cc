#include "indexing/shape_data.h"

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
  d.vertex_displacement.assign(static_cast<size_t>(V) * N * 3, 0.0f);
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
      for (int a = 0; a < 3; ++a) {
        d.vertex_displacement[(static_cast<size_t>(v) * N + n) * 3 + a] =
            static_cast<float>(unskinned(v, a) - mesh.V(v, a));
      }
    }
  });
  d.vertex_shape_start.assign(V + 1, 0);
  for (int v = 0; v < V; ++v) {
    const float* b = d.VertexDisplacements(v);
    for (int n = 0; n < N; ++n) {
      if (b[3 * n] != 0 || b[3 * n + 1] != 0 || b[3 * n + 2] != 0) {
        d.vertex_shapes.push_back(n);
        d.vertex_shape_displacement.insert(d.vertex_shape_displacement.end(),
                                           b + 3 * n, b + 3 * n + 3);
      }
    }
    d.vertex_shape_start[v + 1] = static_cast<int>(d.vertex_shapes.size());
  }
  return d;
}

Vec3 SkinBundle(const ShapeData& data, int bundle, const JawPose& pose,
                const Vec3& u) {
  if (!data.jaw_rig) return u;
  const Rigid3 t = data.jaw_rig->Transform(pose);
  const double w = data.site_jaw_weight[bundle];
  const Vec3 m = data.site_jaw_moment.row(bundle).transpose();
  return (1.0 - w) * u + w * (t * u) + (t.linear() * m - m);
}

Vec3 UnskinBundle(const ShapeData& data, int bundle, const JawPose& pose,
                  const Vec3& p) {
  if (!data.jaw_rig) return p;
  const Rigid3 t = data.jaw_rig->Transform(pose);
  const double w = data.site_jaw_weight[bundle];
  const Vec3 m = data.site_jaw_moment.row(bundle).transpose();
  const Mat3 a = (1.0 - w) * Mat3::Identity() + w * t.linear();
  return a.partialPivLu().solve(p - w * t.translation() -
                                (t.linear() * m - m));
}

}  // namespace hmc
