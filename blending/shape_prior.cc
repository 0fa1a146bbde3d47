#include "blending/shape_prior.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

#include <Eigen/Eigenvalues>

#include "core/error.h"
#include "core/parallel.h"

namespace hmc {

Eigen::VectorXd ChooseShapePrior(
    const BlendshapeSolver& global,
    const std::vector<const std::vector<char>*>& observed,
    const std::vector<Eigen::VectorXd>& disp, double sigma,
    double sigma_floor, int N, double* prior_sigma) {
  *prior_sigma = 0.0;
  if (!(sigma > 0) || disp.empty()) return Eigen::VectorXd::Zero(N);
  const int total = static_cast<int>(disp.size());
  // The frames, grouped by observed set (frames usually share one): one
  // normal matrix, its eigendecomposition, B^T d per frame, and the squared
  // coordinates c_i^2 summed over the frames. Every group costs a
  // factorisation per iteration below, a frame only a triangular solve:
  // kMaxGroups sets at most (taken from frames evenly spaced over the
  // sequence), kMaxFrames frames at most (evenly spaced). Unrelated frames
  // (a dataset's shapes) each use their own shapes, so a sample of them
  // holds the shapes of the others back (robust-global on the dataset with
  // 0.1 mm noise, 96 x 80 actor of seed 1: 0.0328 mm face mean for 32 of
  // its 87 frames, 0.0123 for all).
  constexpr int kMaxGroups = 32;
  constexpr int kMaxFrames = 256;
  struct Group {
    Eigen::MatrixXd H;
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig;
    Eigen::MatrixXd c;  // N x frames: B^T d per frame
    Eigen::VectorXd c2;
  };
  std::map<std::vector<char>, Group> by_set;
  const int count = std::min(total, kMaxFrames);
  std::vector<int> frames;
  for (int j = 0; j < count; ++j) {
    frames.push_back(static_cast<int>((static_cast<int64_t>(j) * total) / count));
  }
  // The groups first from kMaxGroups evenly spaced frames, then every
  // frame whose set is one of them.
  for (int j = 0; j < std::min(count, kMaxGroups); ++j) {
    const int i = frames[static_cast<size_t>((static_cast<int64_t>(j) * count) /
                                             std::min(count, kMaxGroups))];
    by_set.emplace(*observed[i], Group());
  }
  for (int i : frames) {
    auto found = by_set.find(*observed[i]);
    if (found == by_set.end()) continue;
    if (found->second.H.size() == 0) {
      found->second.H = global.Normal(*observed[i]);
      found->second.eig.compute(found->second.H);
      HMC_CHECK(found->second.eig.info() == Eigen::Success);
      found->second.c2 = Eigen::VectorXd::Zero(N);
    }
    Group& g = found->second;
    g.c.conservativeResize(N, g.c.cols() + 1);
    g.c.col(g.c.cols() - 1) = global.Project(disp[i]);
    g.c2 += (g.eig.eigenvectors().transpose() * g.c.rightCols<1>()).cwiseAbs2();
  }
  std::vector<Group*> groups;
  for (auto& [set, group] : by_set) groups.push_back(&group);
  // 1. One variance (and the noise's).
  auto nll = [&](double noise2, double t2) {
    double sum = 0.0;
    for (const Group* g : groups) {
      const Eigen::VectorXd& s = g->eig.eigenvalues();
      const double frames = static_cast<double>(g->c.cols());
      for (int i = 0; i < N; ++i) {
        const double si = std::max(s[i], 1e-12);
        const double var = noise2 * si + t2 * si * si;
        sum += frames * std::log(var) + g->c2[i] / var;
      }
    }
    return sum;
  };
  auto tau_grid = [](int e) { return std::pow(10.0, e / 8.0); };
  double s2 = sigma * sigma;
  if (sigma_floor >= 0) {
    double best = std::numeric_limits<double>::infinity(), best_s2 = s2;
    for (int es = -48; es <= 16; ++es) {
      const double noise2 = sigma * sigma * std::pow(10.0, es / 8.0);
      for (int e = -40; e <= 16; ++e) {
        const double value = nll(noise2, tau_grid(e));
        if (value < best) {
          best = value;
          best_s2 = noise2;
        }
      }
    }
    s2 = std::max(best_s2, sigma_floor * sigma_floor);
  }
  *prior_sigma = std::sqrt(s2);
  double tau2 = 0.0, best = std::numeric_limits<double>::infinity();
  for (int e = -40; e <= 16; ++e) {
    const double value = nll(s2, tau_grid(e));
    if (value < best) {
      best = value;
      tau2 = tau_grid(e);
    }
  }
  // 2. One per shape: 50 fixed-point iterations at most. Correlated shapes
  // keep trading variance slowly, so it is not run to convergence (200
  // iterations instead of 50 changed the face error by ~1 %).
  Eigen::VectorXd t = Eigen::VectorXd::Constant(N, tau2);
  const int G = static_cast<int>(groups.size());
  for (int iter = 0; iter < 50; ++iter) {
    std::vector<Eigen::VectorXd> mu2(G), gamma(G);
    ParallelFor(0, G, [&](int64_t j) {
      const Group& g = *groups[j];
      Eigen::MatrixXd A = g.H / s2;
      A.diagonal() += t.cwiseInverse();
      const Eigen::LLT<Eigen::MatrixXd> llt(A);
      // The frames' posterior means, all at once (one triangular solve of
      // N x frames, not one per frame).
      mu2[j] = llt.solve(g.c / s2).cwiseAbs2().rowwise().sum();
      // diag(A^-1) = squared column norms of L^-1.
      const Eigen::MatrixXd inverse_l =
          llt.matrixL().solve(Eigen::MatrixXd::Identity(N, N));
      gamma[j] = static_cast<double>(g.c.cols()) *
                 (Eigen::VectorXd::Ones(N) -
                  inverse_l.colwise().squaredNorm().transpose().cwiseQuotient(t));
    });
    Eigen::VectorXd num = Eigen::VectorXd::Zero(N), den = num;
    for (int j = 0; j < G; ++j) {
      num += mu2[j];
      den += gamma[j];
    }
    Eigen::VectorXd next(N);
    for (int n = 0; n < N; ++n) {
      next[n] = std::clamp(num[n] / std::max(den[n], 1e-12), 1e-10, 1e4);
    }
    const double change =
        (next.array().log() - t.array().log()).abs().maxCoeff();
    t = next;
    if (change < 1e-3) break;
  }
  return s2 * t.cwiseInverse();
}

}  // namespace hmc
