// The `interp` baseline (docs/baselines.md): the bundles' displacements
// interpolated smoothly over the neutral, with no dataset detail -- what Bhat
// et al. 2013 ("High fidelity facial animation capture and retargeting with
// contours", SCA) call the corrective shape.
//
// Bhat et al. spread the marker corrections with a Laplacian-style smooth
// deformation of the mesh; we use its scattered-data counterpart in head
// space, the 3D biharmonic spline (polyharmonic kernel phi(r) = r plus an
// affine term; Duchon 1977, Carr et al. 2001): it minimises the same kind of
// bending energy, int |Laplacian f|^2, over R^3 instead of over the surface.
// Differences from the mesh version: distances are Euclidean, so the upper
// and lower lip influence each other across the mouth opening (with a jaw
// rig the interpolation runs on unskinned bundles, as lgi does, and the
// result is skinned with the frame's jaw pose, which removes most of that
// coupling); in exchange the per-frame solve is a dense (K+4)^2 system
// independent of the vertex count, robust to missing bundles, and the
// affine term reproduces any affine motion exactly.
//
// Interpolation is exact on the surface: the constraint for bundle k is on
// the mesh's surface point, the functional L_k x = sum_i bary_ki x(v_ki),
// not on the spline at x0(s_k), so the output mesh passes through every
// observed bundle (exactly for the zero jaw pose; with a jaw rig up to the
// skinning of the site's triangle, as for lgi). The basis follows the
// functionals (generalised Hermite-Birkhoff interpolation; Wendland 2005,
// "Scattered Data Approximation", ch. 16):
//   f(x) = sum_j alpha_j sum_i bary_ji |x - x0(v_ji)| + affine(x),
// which makes the system symmetric and uniquely solvable for independent
// functionals (no two bundles at one point, no four in one triangle, four
// not coplanar sites). Bundles whose sites nearly coincide are merged.
#pragma once

#include <Eigen/Core>
#include <Eigen/LU>
#include <string>
#include <unordered_map>
#include <vector>

#include "blending/lgi_solver.h"
#include "core/frame_data.h"
#include "core/mesh.h"
#include "core/options.h"
#include "indexing/shape_data.h"

namespace hmc {

struct InterpOptions {
  double min_bundle_fraction = 0.5;  // frames with fewer observed bundles
                                     // (fraction of markers) are bad; not
                                     // registered: `hmc solve` sets it from
                                     // solve.min_bundle_fraction
  double merge_mm = 0.5;  // bundles whose sites on the neutral are closer
                          // than this share one constraint (their mean):
                          // exact interpolation of nearly coincident sites
                          // is ill-conditioned (mm)

  void Register(OptionFields* fields);
  bool Check() const;
};

class InterpSolver {
 public:
  // neutral (V x 3, triangles) and data must outlive the solver.
  InterpSolver(const TriMesh& neutral, const ShapeData& data,
               const InterpOptions& options);

  // One frame: fills *mesh (V x 3, mm) and each observed bundle's residual
  // when ok.
  FrameSolve SolveFrame(const BundleFrame& bundles, const JawPose& jaw,
                        MatX3d* mesh) const;

  SolveResult SolveSequence(
      const std::vector<BundleFrame>& frames, const std::vector<JawPose>& jaw,
      const std::vector<std::string>& frame_errors = {}) const;

  // The spline on its own (also the smooth correction of lgi-rbf): the
  // displacement field f (V x 3, mm, f(v) at neutral vertex v) whose surface
  // point at each bundle k with observed[k] equals disp[k] (K entries, mm).
  // Returns false and says why in *reason when the observed bundles do not
  // determine the spline (fewer than 4 distinct sites, coplanar sites).
  bool InterpolateDisplacements(const std::vector<Vec3>& disp,
                                const std::vector<char>& observed,
                                MatX3d* field, std::string* reason) const;

 private:
  const TriMesh& neutral_;
  const ShapeData& data_;
  InterpOptions options_;
  std::unordered_map<std::string, int> marker_index_;
  MatX3d centres_;  // K x 3: x0(s_k), the kernel centres (mm)
  // 3K x 3 corners x0(v_ki) of each site's triangle and 3K barycentrics.
  MatX3d corners_;
  Eigen::VectorXd corner_weights_;
  // K x K: collocation[k, j] = L_k psi_j
  //   = sum_a sum_b bary_ka bary_jb |x0(v_ka) - x0(v_jb)|.
  Eigen::MatrixXd collocation_;
  // Bundles whose sites are within options_.merge_mm share one
  // constraint: representative_[k] is the first of k's group.
  std::vector<int> representative_;
  int num_sites_ = 0;                             // number of groups
  Eigen::PartialPivLU<Eigen::MatrixXd> full_lu_;  // every group observed
};

}  // namespace hmc
