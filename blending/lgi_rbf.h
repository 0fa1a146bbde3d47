// The `lgi-rbf` alternative (docs/ARCHITECTURE.md, "Method steps", 10; paper, Cong, Lan,
// Fedkiw, "Local Geometric Indexing of High Resolution Data for Facial
// Reconstruction from Sparse Markers", paragraph "RBF Interpolation"): the
// per-bundle shape weights chosen by local geometric indexing are spread
// over the neutral by Gaussian radial basis function interpolation instead
// of being sewn with natural-neighbour weights, and a smooth correction then
// makes the surface pass through the bundles.
//
// Per frame, with the lgi choice w_k (shape -> weight) of every bundle k
// (inside, projected or filled; blending/lgi_solver.h steps 1-5):
//   1. RBF interpolation of the weight vectors over head space on the
//      neutral: phi(r) = exp(-r^2 / (2 sigma^2)), G_kj = phi(|x0(s_k) -
//      x0(s_j)|), A = (G + ridge I)^-1 W (W: K x N rows w_k), and per vertex
//      w(v) = sum_k phi(|x0(v) - x0(s_k)|) A_k. Since the RBF acts on the
//      shape weights, not on positions, each vertex still carries the
//      dataset's high-resolution detail (the paper's point), with weights
//      that vary smoothly instead of the natural-neighbour blend of per-bundle
//      blends. Kernel values below `cutoff` are dropped (stored sparse).
//   2. y*(v) = x0(v) + sum_n w_n(v) b*_n(v) (unskinned shapes).
//   3. The surface y* does not pass through the bundles; the remaining
//      displacements d_k = p*_k - y*(s_k) of the observed bundles (unskinned)
//      are interpolated with the biharmonic spline of the `interp` baseline
//      (blending/baseline_interp.h; the paper suggests Bhat et al. 2013, which
//      that spline stands in for), exact on the surface points: x* = y* + f.
//   4. Skin with the frame's jaw pose.
// Neutral bundles give zero weights and zero residuals, hence the (skinned)
// neutral. Bad frames follow the lgi conventions (repeat the previous good
// mesh).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <Eigen/Cholesky>
#include <Eigen/SparseCore>

#include "blending/baseline_interp.h"
#include "blending/lgi_solver.h"
#include "core/options.h"

namespace hmc {

struct LgiRbfOptions {
  double sigma_mm = 0.0;     // Gaussian width (mm); 0: sigma_scale times the
                             // median distance of a site to its nearest site
  double sigma_scale = 1.0;  // auto width, in nearest-site distances
  double ridge = 0.1;        // Tikhonov term added to the kernel matrix's
                             // diagonal (the kernel is 1 there): > 0 makes
                             // the weight field smooth rather than exactly
                             // interpolating the bundles' weights, which
                             // tames its oscillation between sites (the
                             // correction still passes through the bundles)
  double cutoff = 1e-6;      // kernel values below this are dropped
  bool correct = true;       // smooth correction through the bundles (off:
                             // the plain RBF result, for comparison)

  void Register(OptionFields* fields);
  bool Check() const;
};

class LgiRbfSolver {
 public:
  // lgi: the local geometric indexing solve whose per-bundle choices are
  // spread (its data and neutral are used here too). All referenced objects
  // must outlive this solver.
  LgiRbfSolver(const TriMesh& neutral, const ShapeData& data,
               const LgiSolver& lgi, const LgiRbfOptions& options,
               const InterpOptions& interp_options = {});

  // Like LgiSolver::SolveSequence (same inputs, bad-frame conventions and
  // diagnostics); the meshes are the RBF blend with the correction, and each
  // observed bundle's residual is that of the output mesh.
  SolveResult SolveSequence(
      const std::vector<BundleFrame>& frames, const std::vector<JawPose>& jaw,
      const std::vector<std::string>& frame_errors = {}) const;

  // The same from the lgi solve of the sequence (LgiSolver::SolveSequence's
  // result, consumed): its meshes are replaced by the RBF blend.
  SolveResult SolveFromLgi(SolveResult lgi_result) const;

  // Steps 1-4 for one frame solved by lgi (its weights, statuses and
  // observed positions). Returns false and sets frame->reason if the
  // correction is undetermined; fills *mesh (V x 3, mm) and the residuals.
  bool Blend(FrameSolve* frame, MatX3d* mesh) const;

  double sigma_mm() const { return sigma_; }

 private:
  const TriMesh& neutral_;
  const ShapeData& data_;
  const LgiSolver& lgi_;
  LgiRbfOptions options_;
  InterpSolver correction_;
  double sigma_ = 0.0;
  Eigen::MatrixXd kernel_;  // K x K: phi(|x0(s_k) - x0(s_j)|) + ridge I
  Eigen::LLT<Eigen::MatrixXd> full_llt_;  // of kernel_, all bundles used
  // V x K: phi(|x0(v) - x0(s_k)|), values below the cutoff dropped.
  Eigen::SparseMatrix<double, Eigen::RowMajor> vertex_kernel_;
};

}  // namespace hmc
