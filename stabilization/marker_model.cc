#include "stabilization/marker_model.h"

#include <cmath>

#include "core/parallel.h"

namespace hmc {

Vec3 MarkerModel::Skin(int k, const Rigid3& t, const Vec3& u) const {
  if (!jaw_rig) return u;
  const double w = jaw_weight[k];
  const Vec3 m = jaw_moment.row(k).transpose();
  return (1.0 - w) * u + w * (t * u) + (t.linear() * m - m);
}

Vec3 MarkerModel::Unskin(int k, const Rigid3& t, const Vec3& p) const {
  if (!jaw_rig) return p;
  const double w = jaw_weight[k];
  const Vec3 m = jaw_moment.row(k).transpose();
  const Mat3 a = (1.0 - w) * Mat3::Identity() + w * t.linear();
  return a.partialPivLu().solve(p - w * t.translation() - (t.linear() * m - m));
}

MarkerModel ComputeMarkerModel(const Actor& actor) {
  MarkerModel model;
  const TriMesh& mesh = actor.neutral;
  const int K = static_cast<int>(actor.markers.size());
  const int N = static_cast<int>(actor.shapes.size());
  model.num_markers = K;
  model.num_shapes = N;
  model.jaw_rig = actor.jaw_rig;
  model.neutral.resize(K, 3);
  model.jaw_weight = Eigen::VectorXd::Zero(K);
  model.jaw_moment = MatX3d::Zero(K, 3);
  for (int k = 0; k < K; ++k) {
    const Marker& marker = actor.markers[k];
    model.names.push_back(marker.name);
    model.index.emplace(marker.name, k);
    model.stable.push_back(marker.HasTag("stable"));
    model.jaw.push_back(marker.HasTag("jaw"));
    model.neutral.row(k) =
        EvaluateSurfacePoint(marker.point, mesh.F, mesh.V).transpose();
    if (!actor.jaw_rig) continue;
    for (int i = 0; i < 3; ++i) {
      const int v = mesh.F(marker.point.face, i);
      const double bw = marker.point.bary[i] * actor.jaw_rig->weights[v];
      model.jaw_weight[k] += bw;
      model.jaw_moment.row(k) += bw * (mesh.V.row(v) - model.neutral.row(k));
    }
  }
  model.displacement.resize(3 * K, N);
  model.unskinned_displacement.resize(3 * K, N);
  ParallelFor(0, N, [&](int64_t n) {
    const Shape& shape = actor.shapes[n];
    const MatX3d positions = mesh.V + shape.displacement;
    const Rigid3 t = actor.jaw_rig ? actor.jaw_rig->Transform(shape.jaw)
                                   : Rigid3::Identity();
    for (int k = 0; k < K; ++k) {
      const Vec3 q = model.neutral.row(k).transpose();
      const Vec3 p =
          EvaluateSurfacePoint(actor.markers[k].point, mesh.F, positions);
      model.displacement.block<3, 1>(3 * k, n) = p - q;
      model.unskinned_displacement.block<3, 1>(3 * k, n) =
          model.Unskin(k, t, p) - q;
    }
  });
  model.motion_rms.resize(K);
  for (int k = 0; k < K; ++k) {
    model.motion_rms[k] =
        N == 0 ? 0.0
               : std::sqrt(model.displacement.middleRows<3>(3 * k)
                               .colwise()
                               .squaredNorm()
                               .mean());
  }
  return model;
}

Eigen::MatrixXd NormalWithout(const Eigen::MatrixXd& normal, const Eigen::MatrixXd& b,
                              const std::vector<char>& used) {
  Eigen::MatrixXd out = normal;
  for (size_t k = 0; k < used.size(); ++k) {
    if (used[k]) continue;
    const auto bk = b.middleRows<3>(3 * k);
    out.noalias() -= bk.transpose() * bk;
  }
  return out;
}

}  // namespace hmc
