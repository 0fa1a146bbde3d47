#include "blending/kernel_smoother.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

namespace hmc {
namespace {

// Random sites in a 60 x 60 x 20 mm slab, about as dense as face markers.
MatX3d RandomSites(int count, std::mt19937* rng) {
  std::uniform_real_distribution<double> xy(-30, 30), z(-10, 10);
  MatX3d sites(count, 3);
  for (int k = 0; k < count; ++k) sites.row(k) = Vec3(xy(*rng), xy(*rng), z(*rng)).transpose();
  return sites;
}

// A smooth displacement field (mm) over head space.
Vec3 Smooth(const Vec3& x) {
  return Vec3(std::sin(x.x() / 15.0), std::cos(x.y() / 12.0),
              0.5 * std::sin((x.x() + x.y()) / 20.0));
}

class KernelSmootherSeeds : public ::testing::TestWithParam<int> {};

// The O(n) residual formula agrees with the coefficients it stands for:
// RSS = |d - G alpha|^2 with G the kernel between the sites.
TEST_P(KernelSmootherSeeds, FitStatisticsMatchTheCoefficients) {
  std::mt19937 rng(GetParam());
  const MatX3d sites = RandomSites(80, &rng);
  const double width = MedianNearestSiteDistance(sites, 10.0);
  const KernelSmoother smoother(sites, width);
  std::vector<char> observed(80, 1);
  observed[3] = observed[17] = 0;
  const KernelSmoother::Basis basis = smoother.MakeBasis(observed);
  ASSERT_EQ(basis.ids.size(), 78u);
  std::normal_distribution<double> noise(0.0, 0.3);
  std::vector<Vec3> d(80);
  for (int k = 0; k < 80; ++k) {
    d[k] = Smooth(sites.row(k).transpose()) +
           Vec3(noise(rng), noise(rng), noise(rng));
  }
  const Eigen::MatrixXd data = smoother.Data(basis, d);
  const auto kernel = GaussianKernelMatrix(sites, sites, width, 1e-12);
  for (double lambda : {1e-3, 0.1, 1.0, 30.0}) {
    SCOPED_TRACE(lambda);
    const Eigen::MatrixXd alpha = smoother.Coefficients(basis, data, lambda);
    EXPECT_EQ(alpha.row(3).norm(), 0.0);
    const Eigen::MatrixXd fitted = kernel * alpha;  // at every site
    EXPECT_LT((smoother.AtSites(alpha) - fitted).norm(),
              1e-9 * (1 + fitted.norm()));
    double rss = 0;
    for (size_t a = 0; a < basis.ids.size(); ++a) {
      rss += (data.row(a) - fitted.row(basis.ids[a])).squaredNorm();
    }
    const KernelFit fit =
        smoother.Fit(basis, basis.vectors.transpose() * data, lambda);
    EXPECT_NEAR(fit.rss, rss, 1e-6 * (1 + rss));
    EXPECT_GT(fit.trace_residual, 0.0);
    EXPECT_LT(fit.trace_residual, 78.0);
    // The fitted values solve (G + lambda I) alpha = d at the data.
    for (size_t a = 0; a < basis.ids.size(); ++a) {
      EXPECT_LT((fitted.row(basis.ids[a]) +
                 lambda * alpha.row(basis.ids[a]) - data.row(a))
                    .norm(),
                1e-6 * (1 + data.norm()));
    }
  }
}

// The leave-one-out identity against refitting without each bundle: the
// fit to the other bundles, evaluated at the one left out, misses it by
// exactly r_i / (1 - H_ii). Infinity predicts zero everywhere.
TEST_P(KernelSmootherSeeds, LeaveOneOutMatchesRefitting) {
  std::mt19937 rng(200 + GetParam());
  const int count = 40;
  const MatX3d sites = RandomSites(count, &rng);
  const double width = 2 * MedianNearestSiteDistance(sites, 10.0);
  const KernelSmoother smoother(sites, width);
  std::vector<char> observed(count, 1);
  observed[5] = 0;
  const KernelSmoother::Basis basis = smoother.MakeBasis(observed);
  std::normal_distribution<double> noise(0.0, 0.3);
  std::vector<Vec3> d(count);
  for (int k = 0; k < count; ++k) {
    d[k] = Smooth(sites.row(k).transpose()) +
           Vec3(noise(rng), noise(rng), noise(rng));
  }
  const Eigen::MatrixXd data = smoother.Data(basis, d);
  const Eigen::MatrixXd z = basis.vectors.transpose() * data;
  const auto kernel = GaussianKernelMatrix(sites, sites, width, 1e-300);
  for (double lambda : {1e-2, 0.3, 3.0, 100.0}) {
    SCOPED_TRACE(lambda);
    double brute = 0;
    for (int left_out : basis.ids) {
      std::vector<char> others = observed;
      others[left_out] = 0;
      const KernelSmoother::Basis b = smoother.MakeBasis(others);
      const Eigen::MatrixXd alpha =
          smoother.Coefficients(b, smoother.Data(b, d), lambda);
      const Vec3 predicted = (kernel.row(left_out) * alpha).transpose();
      brute += (d[left_out] - predicted).squaredNorm();
    }
    EXPECT_NEAR(smoother.LeaveOneOutRss(basis, z, lambda), brute,
                1e-8 * brute);
  }
  double all = 0;
  for (int k : basis.ids) all += d[k].squaredNorm();
  EXPECT_NEAR(smoother.LeaveOneOutRss(
                  basis, z, std::numeric_limits<double>::infinity()),
              all, 1e-10 * all);
}

// Cross-validation finds the noise level of a smooth field plus white noise
// (Wahba's estimate RSS / tr(I - H)), and a known noise level's C_p picks a
// smoothing close to it.
TEST_P(KernelSmootherSeeds, CrossValidationEstimatesTheNoise) {
  std::mt19937 rng(100 + GetParam());
  const MatX3d sites = RandomSites(150, &rng);
  const double spacing = MedianNearestSiteDistance(sites, 10.0);
  const KernelSmoother smoother(sites, 2 * spacing);
  const std::vector<char> observed(150, 1);
  const KernelSmoother::Basis basis = smoother.MakeBasis(observed);
  for (double sigma : {0.1, 0.5}) {
    SCOPED_TRACE(sigma);
    std::normal_distribution<double> noise(0.0, sigma);
    KernelFit best;
    double best_gcv = INFINITY, best_lambda = 0;
    std::vector<Eigen::MatrixXd> z;
    for (int frame = 0; frame < 10; ++frame) {
      std::vector<Vec3> d(150);
      for (int k = 0; k < 150; ++k) {
        d[k] = frame * 0.1 * Smooth(sites.row(k).transpose()) +
               Vec3(noise(rng), noise(rng), noise(rng));
      }
      z.push_back(basis.vectors.transpose() * smoother.Data(basis, d));
    }
    double best_cp = INFINITY, cp_lambda = 0;
    for (int e = -12; e <= 12; ++e) {
      const double lambda = std::pow(10.0, e / 4.0);
      KernelFit fit;
      for (const auto& zf : z) fit.Add(smoother.Fit(basis, zf, lambda));
      if (fit.Gcv() < best_gcv) {
        best_gcv = fit.Gcv();
        best = fit;
        best_lambda = lambda;
      }
      if (fit.Cp(sigma) < best_cp) {
        best_cp = fit.Cp(sigma);
        cp_lambda = lambda;
      }
    }
    EXPECT_NEAR(std::sqrt(best.NoiseVariance()), sigma, 0.1 * sigma);
    EXPECT_LE(std::abs(std::log10(cp_lambda / best_lambda)), 0.51);
  }
}

TEST(KernelSmoother, LargeSmoothingGivesNoCorrection) {
  std::mt19937 rng(7);
  const MatX3d sites = RandomSites(40, &rng);
  const KernelSmoother smoother(sites, 10.0);
  const KernelSmoother::Basis basis =
      smoother.MakeBasis(std::vector<char>(40, 1));
  std::vector<Vec3> d(40, Vec3(1, -2, 0.5));
  const Eigen::MatrixXd alpha =
      smoother.Coefficients(basis, smoother.Data(basis, d), 1e9);
  EXPECT_LT(alpha.cwiseAbs().maxCoeff(), 1e-8);
  // Infinite smoothing is no fit at all, and its statistics say so, as the
  // limit of large smoothings: the residual is the data, tr(I - H) = n.
  const Eigen::MatrixXd data = smoother.Data(basis, d);
  EXPECT_EQ(smoother
                .Coefficients(basis, data,
                              std::numeric_limits<double>::infinity())
                .cwiseAbs()
                .maxCoeff(),
            0.0);
  const Eigen::MatrixXd z = basis.vectors.transpose() * data;
  const KernelFit none =
      smoother.Fit(basis, z, std::numeric_limits<double>::infinity());
  const KernelFit large = smoother.Fit(basis, z, 1e12);
  EXPECT_NEAR(none.rss, data.squaredNorm(), 1e-12 * data.squaredNorm());
  EXPECT_EQ(none.trace_residual, 40.0);
  EXPECT_NEAR(large.rss, none.rss, 1e-6 * none.rss);
  EXPECT_NEAR(large.trace_residual, none.trace_residual, 1e-6);
}

TEST(KernelSmoother, MedianNearestSiteDistance) {
  MatX3d sites(4, 3);
  sites << 0, 0, 0, 1, 0, 0, 5, 0, 0, 5, 0, 0;  // the last two coincide
  // Nearest distinct sites: 1, 1, 4, 4 -> median (upper) 4.
  EXPECT_DOUBLE_EQ(MedianNearestSiteDistance(sites, 10.0), 4.0);
  EXPECT_DOUBLE_EQ(MedianNearestSiteDistance(MatX3d::Zero(1, 3), 10.0), 10.0);
}

INSTANTIATE_TEST_SUITE_P(Seeds, KernelSmootherSeeds, ::testing::Values(1, 2, 3));

}  // namespace
}  // namespace hmc
