#include "blending/kernel_smoother.h"

#include <Eigen/Eigenvalues>
#include <Eigen/SparseCore>
#include <algorithm>
#include <cmath>
#include <limits>

#include "core/error.h"
#include "core/error_stats.h"
#include "core/parallel.h"

namespace hmc {

namespace {

double Gaussian(double squared_distance, double sigma) {
  return std::exp(-squared_distance / (2 * sigma * sigma));
}

}  // namespace

double MedianNearestSiteDistance(const MatX3d& sites, double fallback) {
  const int K = static_cast<int>(sites.rows());
  std::vector<double> nearest;
  for (int k = 0; k < K; ++k) {
    double best = std::numeric_limits<double>::infinity();
    for (int j = 0; j < K; ++j) {
      const double d = (sites.row(k) - sites.row(j)).norm();
      if (j != k && d > 1e-9) best = std::min(best, d);
    }
    if (std::isfinite(best)) nearest.push_back(best);
  }
  if (nearest.empty()) return fallback;
  return UpperMedian(&nearest);
}

Eigen::SparseMatrix<double, Eigen::RowMajor> GaussianKernelMatrix(
    const MatX3d& points, const MatX3d& centres, double sigma, double cutoff) {
  HMC_CHECK(sigma > 0 && cutoff > 0 && cutoff < 1);
  const int V = static_cast<int>(points.rows());
  const int K = static_cast<int>(centres.rows());
  const double radius2 = -2 * sigma * sigma * std::log(cutoff);
  std::vector<std::vector<std::pair<int, double>>> rows(V);
  ParallelFor(
      0, V,
      [&](int64_t v) {
        for (int k = 0; k < K; ++k) {
          const double d2 = (points.row(v) - centres.row(k)).squaredNorm();
          if (d2 <= radius2) rows[v].emplace_back(k, Gaussian(d2, sigma));
        }
      },
      256);
  std::vector<Eigen::Triplet<double>> triplets;
  for (int v = 0; v < V; ++v) {
    for (const auto& [k, g] : rows[v]) triplets.emplace_back(v, k, g);
  }
  Eigen::SparseMatrix<double, Eigen::RowMajor> matrix(V, K);
  matrix.setFromTriplets(triplets.begin(), triplets.end());
  return matrix;
}

void KernelFit::Add(const KernelFit& other) {
  rss += other.rss;
  trace_residual += other.trace_residual;
  n += other.n;
}

double KernelFit::Gcv() const {
  if (!(trace_residual > 0)) return std::numeric_limits<double>::infinity();
  return n * rss / (3.0 * trace_residual * trace_residual);
}

double KernelFit::Cp(double sigma) const {
  // tr(H) = n - tr(I - H) per coordinate.
  const double trace_h = n - trace_residual;
  return rss - 3.0 * sigma * sigma * (n - 2.0 * trace_h);
}

double KernelFit::NoiseVariance() const {
  if (!(trace_residual > 0)) return 0.0;
  return rss / (3.0 * trace_residual);
}

KernelSmoother::KernelSmoother(const MatX3d& sites, double width)
    : sites_(sites), width_(width) {
  HMC_CHECK(width > 0);
  const int K = static_cast<int>(sites.rows());
  kernel_.resize(K, K);
  for (int k = 0; k < K; ++k) {
    for (int j = 0; j < K; ++j) {
      kernel_(k, j) =
          Gaussian((sites.row(k) - sites.row(j)).squaredNorm(), width);
    }
  }
}

KernelSmoother::Basis KernelSmoother::MakeBasis(
    const std::vector<char>& observed) const {
  HMC_CHECK(static_cast<Eigen::Index>(observed.size()) == kernel_.rows());
  Basis basis;
  for (int k = 0; k < static_cast<int>(observed.size()); ++k) {
    if (observed[k]) basis.ids.push_back(k);
  }
  const int n = static_cast<int>(basis.ids.size());
  Eigen::MatrixXd g(n, n);
  for (int a = 0; a < n; ++a) {
    for (int b = 0; b < n; ++b) g(a, b) = kernel_(basis.ids[a], basis.ids[b]);
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(g);
  HMC_CHECK(eig.info() == Eigen::Success);
  basis.vectors = eig.eigenvectors();
  // The Gaussian kernel is positive semi-definite; round-off below zero is
  // clamped (coincident sites give exact zeros, which lambda > 0 handles).
  basis.mu = eig.eigenvalues().cwiseMax(0.0);
  return basis;
}

Eigen::MatrixXd KernelSmoother::Data(const Basis& basis,
                                     const std::vector<Vec3>& d) const {
  Eigen::MatrixXd data(basis.ids.size(), 3);
  for (size_t a = 0; a < basis.ids.size(); ++a) {
    data.row(a) = d[basis.ids[a]].transpose();
  }
  return data;
}

KernelFit KernelSmoother::Fit(const Basis& basis, const Eigen::MatrixXd& z,
                              double lambda) const {
  HMC_CHECK(z.rows() == basis.mu.size() && z.cols() == 3 && lambda > 0);
  KernelFit fit;
  fit.n = static_cast<double>(basis.ids.size());
  for (int i = 0; i < basis.mu.size(); ++i) {
    const double shrink =
        std::isinf(lambda) ? 1.0 : lambda / (basis.mu[i] + lambda);
    fit.rss += shrink * shrink * z.row(i).squaredNorm();
    fit.trace_residual += shrink;
  }
  return fit;
}

double KernelSmoother::LeaveOneOutRss(const Basis& basis,
                                      const Eigen::MatrixXd& z,
                                      double lambda) const {
  HMC_CHECK(z.rows() == basis.mu.size() && z.cols() == 3 && lambda > 0);
  if (std::isinf(lambda)) return z.squaredNorm();  // U is orthogonal
  // H = U diag(mu / (mu + lambda)) U^T, r = U diag(lambda / (mu + lambda)) z.
  const Eigen::VectorXd shrink =
      (lambda / (basis.mu.array() + lambda)).matrix();
  const Eigen::MatrixXd r = basis.vectors * (shrink.asDiagonal() * z);
  const Eigen::VectorXd h_diag = basis.vectors.array().square().matrix() *
                                 (1.0 - shrink.array()).matrix();
  double rss = 0.0;
  for (Eigen::Index i = 0; i < r.rows(); ++i) {
    rss += r.row(i).squaredNorm() / ((1.0 - h_diag[i]) * (1.0 - h_diag[i]));
  }
  return rss;
}

Eigen::MatrixXd KernelSmoother::Coefficients(const Basis& basis,
                                             const Eigen::MatrixXd& data,
                                             double lambda) const {
  HMC_CHECK(lambda > 0);
  const Eigen::VectorXd scale = (basis.mu.array() + lambda).inverse().matrix();
  const Eigen::MatrixXd alpha =
      basis.vectors * (scale.asDiagonal() * (basis.vectors.transpose() * data));
  Eigen::MatrixXd full = Eigen::MatrixXd::Zero(kernel_.rows(), 3);
  for (size_t a = 0; a < basis.ids.size(); ++a) {
    full.row(basis.ids[a]) = alpha.row(a);
  }
  return full;
}

}  // namespace hmc
