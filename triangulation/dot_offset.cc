#include "triangulation/dot_offset.h"

#include <cmath>

#include <Eigen/Dense>

#include "core/mesh.h"

namespace hmc {

std::map<std::string, Vec3> DotRimOffsets(const Actor& actor, double dot_radius,
                                          double fit_radius) {
  const MatX3d& V = actor.neutral.V;
  const MatX3i& F = actor.neutral.F;
  const MatX3d normals = VertexNormals(V, F);
  std::map<std::string, Vec3> out;
  for (const Marker& marker : actor.markers) {
    const Vec3 p = EvaluateSurfacePoint(marker.point, F, V);
    Vec3 n = Vec3::Zero();
    for (int i = 0; i < 3; ++i) n += marker.point.bary[i] * normals.row(F(marker.point.face, i)).transpose();
    if (!(n.norm() > 0)) continue;
    n.normalize();
    const Vec3 t1 = (std::abs(n.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY()).cross(n).normalized();
    const Vec3 t2 = n.cross(t1);
    std::vector<Eigen::Matrix<double, 1, 6>> rows;
    std::vector<double> rhs;
    for (int v = 0; v < V.rows(); ++v) {
      const Vec3 d = V.row(v).transpose() - p;
      if (d.squaredNorm() > fit_radius * fit_radius) continue;
      if (normals.row(v).dot(n) < 0.5) continue;  // the other lip, the far side of a fold
      const double x = d.dot(t1), y = d.dot(t2);
      Eigen::Matrix<double, 1, 6> row;
      row << x * x, x * y, y * y, x, y, 1;
      rows.push_back(row);
      rhs.push_back(d.dot(n));
    }
    if (rows.size() < 10) continue;
    Eigen::MatrixXd A(rows.size(), 6);
    Eigen::VectorXd b(rows.size());
    for (size_t i = 0; i < rows.size(); ++i) {
      A.row(i) = rows[i];
      b[i] = rhs[i];
    }
    const Eigen::VectorXd q = A.colPivHouseholderQr().solve(b);
    out[marker.name] = (q[0] + q[2]) * dot_radius * dot_radius / 2 * n;
  }
  return out;
}

}  // namespace hmc
