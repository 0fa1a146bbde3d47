#include "synth/face_model.h"

#include <cmath>

#include "core/error.h"
#include "core/parallel.h"
#include "synth/synth_actor.h"

namespace hmc {
namespace {

Eigen::VectorXd Clamped(const Eigen::VectorXd& a, int num_units) {
  HMC_CHECK_MSG(a.size() == num_units,
                "expected " + std::to_string(num_units) + " activations");
  return a.cwiseMax(0.0).cwiseMin(1.0);
}

}  // namespace

double FaceModel::Saturate(double length) {
  if (length <= kSaturationKnee) return length;
  const double room = kSaturationLimit - kSaturationKnee;
  return kSaturationKnee + room * std::tanh((length - kSaturationKnee) / room);
}

VertexContext FaceModel::ContextOf(int64_t v, const MatX3d& normals) const {
  VertexContext context;
  context.st = face_.st.row(v).transpose();
  context.normal = normals.row(v).transpose();
  context.jaw_weight = face_.jaw_rig.weights[v];
  return context;
}

FaceModel::FaceModel(const SynthActorOptions& options)
    : face_(BuildFaceMesh(
          DrawFaceProportions(static_cast<uint64_t>(options.seed),
                              options.proportion_jitter),
          options.grid_u, options.grid_v)),
      catalog_(BuildUnitCatalog(face_.proportions, options.detail_scale)),
      linear_(options.rig == "linear" || options.rig == "broad"),
      broad_(options.rig == "broad") {
  if (broad_) AddBroadRegions(face_.proportions, &catalog_);
  const int num_vertices = NumVertices();
  const MatX3d normals = VertexNormals(face_.mesh.V, face_.mesh.F);
  const int num_terms = static_cast<int>(catalog_.terms.size());
  // Evaluate every term's field at every vertex (parallel over vertices),
  // keeping the non-zero entries in term order.
  std::vector<std::vector<std::pair<int, Vec3>>> per_vertex(num_vertices);
  ParallelFor(0, num_vertices, [&](int64_t v) {
    const VertexContext context = ContextOf(v, normals);
    for (int j = 0; j < num_terms; ++j) {
      const Vec3 f = catalog_.terms[j].field(context);
      if (f.squaredNorm() > 1e-16) per_vertex[v].emplace_back(j, f);
    }
  }, 64);
  offsets_.assign(num_vertices + 1, 0);
  for (int v = 0; v < num_vertices; ++v) {
    offsets_[v + 1] = offsets_[v] + static_cast<int64_t>(per_vertex[v].size());
  }
  term_.resize(offsets_.back());
  field_.resize(offsets_.back());
  for (int v = 0; v < num_vertices; ++v) {
    int64_t e = offsets_[v];
    for (const auto& [j, f] : per_vertex[v]) {
      term_[e] = j;
      field_[e] = f;
      ++e;
    }
  }
  if (linear_) BuildLinearRig();
}

void FaceModel::BuildLinearRig() {
  const int num_vertices = NumVertices(), num_units = NumUnits();
  const MatX3d normals = VertexNormals(face_.mesh.V, face_.mesh.F);
  std::vector<std::vector<std::pair<int, Vec3>>> per_vertex(num_vertices);
  for (int k = 0; k < num_units; ++k) {
    Eigen::VectorXd a = ZeroActivations();
    a[k] = 1.0;
    MatX3d extreme = Skin(face_.jaw_rig, catalog_.jaw_pose(a), Displace(a));
    if (broad_) {
      // The broad rig: the unit's artist-style region on top of its extreme.
      ParallelFor(0, num_vertices, [&](int64_t v) {
        extreme.row(v) += catalog_.broad[k](ContextOf(v, normals)).transpose();
      }, 1024);
    }
    for (int v = 0; v < num_vertices; ++v) {
      const Vec3 d = (extreme.row(v) - face_.mesh.V.row(v)).transpose();
      if (d.squaredNorm() > 1e-16) per_vertex[v].emplace_back(k, d);
    }
  }
  unit_offsets_.assign(num_vertices + 1, 0);
  for (int v = 0; v < num_vertices; ++v) {
    unit_offsets_[v + 1] =
        unit_offsets_[v] + static_cast<int64_t>(per_vertex[v].size());
  }
  unit_.resize(unit_offsets_.back());
  unit_field_.resize(unit_offsets_.back());
  for (int v = 0; v < num_vertices; ++v) {
    int64_t e = unit_offsets_[v];
    for (const auto& [k, d] : per_vertex[v]) {
      unit_[e] = k;
      unit_field_[e] = d;
      ++e;
    }
  }
}

MatX3d FaceModel::DisplaceLinear(const Eigen::VectorXd& a_in) const {
  const Eigen::VectorXd a = Clamped(a_in, NumUnits());
  const MatX3d& x0 = face_.mesh.V;
  MatX3d out(x0.rows(), 3);
  ParallelFor(0, x0.rows(), [&](int64_t v) {
    Vec3 d = Vec3::Zero();
    for (int64_t e = unit_offsets_[v]; e < unit_offsets_[v + 1]; ++e) {
      d += a[unit_[e]] * unit_field_[e];
    }
    out.row(v) = x0.row(v) + d.transpose();
  }, 1024);
  return out;
}

JawPose FaceModel::JawPoseOf(const Eigen::VectorXd& a) const {
  if (linear_) {
    Clamped(a, NumUnits());  // the same size check
    return JawPose();
  }
  return catalog_.jaw_pose(Clamped(a, NumUnits()));
}

MatX3d FaceModel::Displace(const Eigen::VectorXd& a_in) const {
  const Eigen::VectorXd a = Clamped(a_in, NumUnits());
  const int num_terms = static_cast<int>(catalog_.terms.size());
  Eigen::VectorXd c(num_terms);
  for (int j = 0; j < num_terms; ++j) c[j] = catalog_.terms[j].coefficient(a);
  const MatX3d& x0 = face_.mesh.V;
  MatX3d out(x0.rows(), 3);
  ParallelFor(0, x0.rows(), [&](int64_t v) {
    Vec3 d = Vec3::Zero();
    for (int64_t e = offsets_[v]; e < offsets_[v + 1]; ++e) {
      d += c[term_[e]] * field_[e];
    }
    const double length = d.norm();
    if (length > kSaturationKnee) d *= Saturate(length) / length;
    out.row(v) = x0.row(v) + d.transpose();
  }, 1024);
  return out;
}

MatX3d FaceModel::EvaluateUnskinned(const Eigen::VectorXd& a) const {
  return linear_ ? DisplaceLinear(a) : Displace(a);
}

MatX3d FaceModel::Evaluate(const Eigen::VectorXd& a) const {
  if (linear_) return DisplaceLinear(a);
  return Skin(face_.jaw_rig, JawPoseOf(a), Displace(a));
}

}  // namespace hmc
