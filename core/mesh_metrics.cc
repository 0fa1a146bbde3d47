#include "core/mesh_metrics.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/error.h"
#include "core/parallel.h"

namespace hmc {

void MeshMetricsOptions::Register(OptionFields* fields) {
  fields->Add("face_radius_mm", &face_radius_mm,
              "face region: vertices within this distance of the nearest "
              "marker on the neutral (mm)")
      .Above(0);
}

bool MeshMetricsOptions::Check() const {
  CHECK_OPTION_LIMITS();
  return true;
}

Eigen::VectorXd VertexErrors(const MatX3d& truth, const MatX3d& recon) {
  HMC_CHECK(truth.rows() == recon.rows());
  return (truth - recon).rowwise().norm();
}

std::vector<uint8_t> FaceRegionMask(const TriMesh& neutral,
                                    const std::vector<SurfacePoint>& sites,
                                    double radius_mm) {
  const int V = neutral.NumVertices();
  std::vector<Vec3> points;
  points.reserve(sites.size());
  for (const SurfacePoint& s : sites) {
    points.push_back(EvaluateSurfacePoint(s, neutral.F, neutral.V));
  }
  std::vector<uint8_t> mask(V, 0);
  const double r2 = radius_mm * radius_mm;
  ParallelFor(
      0, V,
      [&](int64_t v) {
        const Vec3 x = neutral.V.row(v).transpose();
        for (const Vec3& p : points) {
          if ((x - p).squaredNorm() <= r2) {
            mask[v] = 1;
            return;
          }
        }
      },
      256);
  return mask;
}

Eigen::SparseMatrix<double> UniformLaplacian(const MatX3i& F,
                                             int num_vertices) {
  std::vector<std::vector<int>> neighbours(num_vertices);
  for (int t = 0; t < F.rows(); ++t) {
    for (int i = 0; i < 3; ++i) {
      const int a = F(t, i), b = F(t, (i + 1) % 3);
      neighbours[a].push_back(b);
      neighbours[b].push_back(a);
    }
  }
  std::vector<Eigen::Triplet<double>> triplets;
  for (int v = 0; v < num_vertices; ++v) {
    auto& n = neighbours[v];
    std::sort(n.begin(), n.end());
    n.erase(std::unique(n.begin(), n.end()), n.end());
    if (n.empty()) continue;
    triplets.emplace_back(v, v, 1.0);
    const double w = -1.0 / static_cast<double>(n.size());
    for (int u : n) triplets.emplace_back(v, u, w);
  }
  Eigen::SparseMatrix<double> L(num_vertices, num_vertices);
  L.setFromTriplets(triplets.begin(), triplets.end());
  return L;
}

Eigen::VectorXd DetailErrors(const Eigen::SparseMatrix<double>& L,
                             const MatX3d& truth, const MatX3d& recon) {
  HMC_CHECK(truth.rows() == recon.rows() && L.rows() == truth.rows());
  const Eigen::MatrixXd diff = truth - recon;
  const Eigen::MatrixXd delta = L * diff;
  return delta.rowwise().norm();
}

std::vector<double> Select(const Eigen::VectorXd& values,
                           const std::vector<uint8_t>& mask) {
  std::vector<double> out;
  out.reserve(values.size());
  for (int64_t i = 0; i < values.size(); ++i) {
    if (mask.empty() || mask[i]) out.push_back(values[i]);
  }
  return out;
}

std::vector<double> BundleResiduals(const MatX3i& F,
                                    const std::vector<SurfacePoint>& sites,
                                    const MatX3d& recon,
                                    const MatX3d& targets) {
  HMC_CHECK(targets.rows() == static_cast<int64_t>(sites.size()));
  std::vector<double> out;
  for (size_t k = 0; k < sites.size(); ++k) {
    if (!targets.row(k).allFinite()) continue;
    const Vec3 x = EvaluateSurfacePoint(sites[k], F, recon);
    out.push_back((x - targets.row(k).transpose()).norm());
  }
  return out;
}

}  // namespace hmc
