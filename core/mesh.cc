#include "core/mesh.h"

#include <algorithm>
#include <limits>

#include <fmt/format.h>

#include "core/error.h"
#include "core/triangle.h"

namespace hmc {

Vec3 EvaluateSurfacePoint(const SurfacePoint& point, const MatX3i& F,
                          const MatX3d& X) {
  HMC_CHECK(point.face >= 0 && point.face < F.rows());
  Vec3 x = Vec3::Zero();
  for (int i = 0; i < 3; ++i) {
    x += point.bary[i] * X.row(F(point.face, i)).transpose();
  }
  return x;
}

void CheckSiteOnMesh(const TriMesh& mesh, const SurfacePoint& site, size_t k) {
  if (site.face < 0 || site.face >= mesh.NumFaces()) {
    throw InputError(fmt::format("site {} lies on triangle {}, which the "
                                 "neutral mesh (F = {}) does not have",
                                 k, site.face, mesh.NumFaces()));
  }
}

SurfacePoint ClosestSurfacePoint(const TriMesh& mesh, const Vec3& p, int first_face,
                                 int end_face) {
  if (end_face < 0) end_face = mesh.NumFaces();
  SurfacePoint best;
  double best_d2 = std::numeric_limits<double>::infinity();
  for (int f = first_face; f < end_face; ++f) {
    const Vec3 a = mesh.V.row(mesh.F(f, 0)), b = mesh.V.row(mesh.F(f, 1)),
               c = mesh.V.row(mesh.F(f, 2));
    // Cheap rejection: the triangle's bounding sphere.
    const Vec3 centre = (a + b + c) / 3;
    const double r = std::max({(a - centre).norm(), (b - centre).norm(), (c - centre).norm()});
    const double dc = (p - centre).norm() - r;
    if (dc > 0 && dc * dc > best_d2) continue;
    const Vec3 w = ClosestPointBarycentrics(p, a, b, c);
    const double d2 = (w[0] * a + w[1] * b + w[2] * c - p).squaredNorm();
    if (d2 < best_d2) {
      best_d2 = d2;
      best.face = f;
      best.bary = w;
    }
  }
  return best;
}

SurfacePoint SurfacePointAtVertex(const MatX3i& F, int v) {
  for (int f = 0; f < F.rows(); ++f) {
    for (int i = 0; i < 3; ++i) {
      if (F(f, i) == v) {
        SurfacePoint point;
        point.face = f;
        point.bary = Vec3::Zero();
        point.bary[i] = 1.0;
        return point;
      }
    }
  }
  HMC_CHECK_MSG(false, "vertex " + std::to_string(v) + " is in no triangle");
  return {};
}

MatX2d PerVertexUVs(const TriMesh& mesh) {
  if (!mesh.HasUVs()) return MatX2d();
  MatX2d uv(mesh.NumVertices(), 2);
  std::vector<bool> set(mesh.NumVertices(), false);
  uv.setZero();
  for (int f = 0; f < mesh.NumFaces(); ++f) {
    for (int i = 0; i < 3; ++i) {
      const int v = mesh.F(f, i);
      if (!set[v]) {
        uv.row(v) = mesh.UV.row(mesh.FUV(f, i));
        set[v] = true;
      }
    }
  }
  return uv;
}

MatX3d VertexNormals(const MatX3d& V, const MatX3i& F) {
  MatX3d N = MatX3d::Zero(V.rows(), 3);
  for (int f = 0; f < F.rows(); ++f) {
    const Vec3 a = V.row(F(f, 0)), b = V.row(F(f, 1)), c = V.row(F(f, 2));
    const Vec3 n = (b - a).cross(c - a);  // Length = 2 x area.
    for (int i = 0; i < 3; ++i) N.row(F(f, i)) += n.transpose();
  }
  for (int v = 0; v < N.rows(); ++v) {
    const double norm = N.row(v).norm();
    if (norm > 0) N.row(v) /= norm;
  }
  return N;
}

Eigen::Matrix<double, 2, 3> BoundingBox(const MatX3d& X) {
  Eigen::Matrix<double, 2, 3> box;
  box.row(0) = X.colwise().minCoeff();
  box.row(1) = X.colwise().maxCoeff();
  return box;
}

}  // namespace hmc
