// Gaussian-kernel smoothing of per-bundle displacements over the neutral
// (kernel ridge regression; Wahba 1990, "Spline Models for Observational
// Data", ch. 4, for the cross-validation): the field
//   f(x) = sum_k alpha_k phi(|x - x0(s_k)|),  phi(r) = exp(-r^2 / (2 w^2)),
//   (G + lambda I) alpha = d,   G_kj = phi(|x0(s_k) - x0(s_j)|),
// fitted to displacements d (one per observed bundle). lambda = 0
// interpolates; lambda -> infinity gives f = 0. Unlike a polyharmonic spline
// it has no polynomial part, so it decays to zero away from the bundles and
// a fit to pure noise cannot tilt the far field.
//
// With G = U diag(mu) U^T and z = U^T d, the residual at the data is
//   d - G alpha = U diag(lambda / (mu + lambda)) z,
// so its sum of squares and the trace of I - H (H: the influence matrix)
// cost O(n) per lambda: generalised cross-validation (choosing lambda, and
// estimating the noise variance RSS / tr(I - H)) and Mallows' C_p (lambda
// for a known noise level) are cheap over a grid of lambdas and widths.
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <vector>

#include "core/mesh.h"

namespace hmc {

// The median over sites of the distance to the nearest other site (sites
// closer than 1e-9 mm count as one); `fallback` when there are fewer than
// two distinct sites.
double MedianNearestSiteDistance(const MatX3d& sites, double fallback);

// V x K: phi(|x_v - c_k|) for the rows of `points` (V x 3) and `centres`
// (K x 3), Gaussian of width sigma (mm), values below `cutoff` dropped.
Eigen::SparseMatrix<double, Eigen::RowMajor> GaussianKernelMatrix(
    const MatX3d& points, const MatX3d& centres, double sigma, double cutoff);

// Fit statistics of one lambda, summed over frames (Add) so one lambda can
// be chosen for a sequence: the residual sum of squares over x, y, z
// (mm^2), the trace of I - H per coordinate, and the data per coordinate.
struct KernelFit {
  double rss = 0.0;
  double trace_residual = 0.0;
  double n = 0.0;
  void Add(const KernelFit& other);
  // Generalised cross-validation n RSS / (3 tr(I - H)^2); infinite when
  // tr(I - H) = 0.
  double Gcv() const;
  // Mallows' C_p, the unbiased estimate of the error at the data for noise
  // of known std sigma per coordinate: RSS - 3 sigma^2 (n - 2 tr(H)).
  double Cp(double sigma) const;
  // The noise variance per coordinate the fit implies: RSS / (3 tr(I - H)).
  double NoiseVariance() const;
};

class KernelSmoother {
 public:
  // sites: K x 3 kernel centres x0(s_k) (mm); width: the Gaussian's w (mm).
  KernelSmoother(const MatX3d& sites, double width);

  // The eigen-decomposition of G over one set of observed bundles.
  struct Basis {
    std::vector<int> ids;       // the observed bundles
    Eigen::MatrixXd vectors;    // U: n x n
    Eigen::VectorXd mu;         // eigenvalues (>= 0)
  };
  Basis MakeBasis(const std::vector<char>& observed) const;

  // d (K entries, only the observed ones used) as n x 3 data over `basis`,
  // and its projections z = U^T d.
  Eigen::MatrixXd Data(const Basis& basis, const std::vector<Vec3>& d) const;
  // lambda > 0; infinity: f = 0 (RSS = |d|^2, tr(I - H) = n).
  KernelFit Fit(const Basis& basis, const Eigen::MatrixXd& z,
                double lambda) const;

  // The leave-one-out residual sum of squares over x, y, z (mm^2) of the fit
  // with smoothing lambda: sum_i |r_i|^2 / (1 - H_ii)^2, r the fit's
  // residual at the data; for this linear smoother r_i / (1 - H_ii) is
  // exactly the error with which the fit to the other bundles predicts
  // bundle i. Infinity: |d|^2 (no correction predicts zero).
  double LeaveOneOutRss(const Basis& basis, const Eigen::MatrixXd& z,
                        double lambda) const;

  // The coefficients alpha (K x 3, zero for unobserved bundles) of the fit
  // to data (n x 3) with smoothing lambda > 0 (infinity: all zero).
  Eigen::MatrixXd Coefficients(const Basis& basis, const Eigen::MatrixXd& data,
                               double lambda) const;

  // The fit at every site, G alpha (K x 3), for coefficients alpha (K x 3).
  Eigen::MatrixXd AtSites(const Eigen::MatrixXd& alpha) const {
    return kernel_ * alpha;
  }

  double width() const { return width_; }

 private:
  MatX3d sites_;
  double width_;
  Eigen::MatrixXd kernel_;  // K x K
};

}  // namespace hmc
