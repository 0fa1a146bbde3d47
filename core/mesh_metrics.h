// Reconstruction error metrics for `hmc eval` (and the experiment): per-vertex
// position errors and their statistics, the face region they are measured
// over, the bundle residual and a detail error that measures lost wrinkles.
//
// Face region: the vertices whose head-space distance on the neutral to the
// nearest marker's surface point is at most `face_radius_mm`. Markers are
// painted where the face moves and is observed, so this is the part of the
// mesh a capture can be held accountable for; the back of the head, the neck
// and the inside of the mouth far from any marker are left out. Measured on
// the neutral, so the region is the same for every frame and method.
//
// Detail error: difference of uniform-Laplacian ("umbrella") coordinates,
//   delta(v) = x(v) - mean_{u in N(v)} x(u)   (mm),
// |delta_truth(v) - delta_recon(v)| per vertex. It is zero for identical
// meshes and for any translation, nearly zero for a smooth low-frequency
// offset, and large where folds and wrinkles (high-frequency detail) differ.
// The uniform rather than the cotangent Laplacian: it keeps millimetres as
// the unit (the cotangent version is a curvature, 1/mm) and has no negative
// weights on the obtuse triangles of thin folds.
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <cstdint>
#include <vector>

#include "core/error_stats.h"  // ErrorStats, ComputeErrorStats
#include "core/mesh.h"
#include "core/options.h"
#include "core/types.h"

namespace hmc {

struct MeshMetricsOptions {
  double face_radius_mm = 12.0;  // face region: vertices within this distance
                                 // of the nearest marker on the neutral (mm)

  void Register(OptionFields* fields);
  bool Check() const;
};

// |truth(v) - recon(v)| per vertex. truth, recon: V x 3 (mm). Returns V.
Eigen::VectorXd VertexErrors(const MatX3d& truth, const MatX3d& recon);

// The face region (see above): 1 for vertices within `radius_mm` of the
// nearest of `sites` evaluated on the neutral, else 0. Returns V.
// neutral: V x 3 positions (mm) and triangles; sites: marker surface points.
std::vector<uint8_t> FaceRegionMask(const TriMesh& neutral,
                                    const std::vector<SurfacePoint>& sites,
                                    double radius_mm);

// The uniform Laplacian L (V x V): (L x)(v) = x(v) - mean of v's edge
// neighbours; zero rows for isolated vertices. F: F x 3 triangles.
Eigen::SparseMatrix<double> UniformLaplacian(const MatX3i& F, int num_vertices);

// |L truth - L recon| per vertex (mm). L from UniformLaplacian; truth,
// recon: V x 3. Returns V.
Eigen::VectorXd DetailErrors(const Eigen::SparseMatrix<double>& L,
                             const MatX3d& truth, const MatX3d& recon);

// Values of `values` where mask is non-zero (mask empty: all of them).
std::vector<double> Select(const Eigen::VectorXd& values,
                           const std::vector<uint8_t>& mask);

// Per-marker residual |recon(s_k) - target_k| (mm). targets: K x 3; rows
// with a NaN are markers without a target (skipped). F: triangles;
// recon: V x 3. Returns the residuals of the markers with a target.
std::vector<double> BundleResiduals(const MatX3i& F,
                                    const std::vector<SurfacePoint>& sites,
                                    const MatX3d& recon, const MatX3d& targets);

}  // namespace hmc
