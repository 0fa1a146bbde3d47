#include "blending/baseline_blendshape.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>

#include "core/jaw.h"
#include "synth/synth_actor.h"

namespace hmc {
namespace {

Actor SmallActor(int seed, bool inbetweens) {
  SynthActorOptions o;
  o.seed = seed;
  o.grid_u = 40;
  o.grid_v = 32;
  o.dataset_inbetweens = inbetweens;
  o.dataset_combos = false;
  return SynthesizeActor(o);
}

// Bundles of the blend x0 + sum w_n b*_n at the sites, skinned by `jaw`.
BundleFrame BundlesOf(const ShapeData& data, const Eigen::VectorXd& w,
                      const JawPose& jaw, int frame) {
  BundleFrame b;
  b.frame = frame;
  for (int k = 0; k < data.num_bundles; ++k) {
    Vec3 u = data.site_neutral.row(k).transpose();
    for (int n = 0; n < data.num_shapes; ++n) {
      u += w[n] * data.SiteDisplacement(n, k);
    }
    b.bundles[data.bundle_names[k]] = SkinBundle(data, k, jaw, u);
  }
  return b;
}

// The objective the solvers minimise, in their (1/2 Q, c) form.
double Objective(const Eigen::MatrixXd& Q, const Eigen::VectorXd& c,
                 const Eigen::VectorXd& w) {
  return 0.5 * w.dot(Q * w) - c.dot(w);
}

class BoxQp : public ::testing::TestWithParam<int> {};

// Brute force over every assignment of each variable to {lower bound, upper
// bound, free}: the feasible stationary points include the optimum.
TEST_P(BoxQp, BoundedMatchesEnumerationOfActiveSets) {
  std::mt19937 rng(GetParam());
  std::normal_distribution<double> g(0, 1);
  const int N = 4;
  for (int trial = 0; trial < 20; ++trial) {
    Eigen::MatrixXd A(6, N);
    for (int i = 0; i < A.size(); ++i) A.data()[i] = g(rng);
    const Eigen::MatrixXd Q =
        A.transpose() * A + 1e-3 * Eigen::MatrixXd::Identity(N, N);
    Eigen::VectorXd c(N);
    for (int i = 0; i < N; ++i) c[i] = 2 * g(rng);
    double best = 1e300;
    for (int code = 0; code < 81; ++code) {
      Eigen::VectorXd w = Eigen::VectorXd::Zero(N);
      std::vector<int> free;
      int x = code;
      for (int i = 0; i < N; ++i, x /= 3) {
        if (x % 3 == 1) w[i] = 1;
        if (x % 3 == 2) free.push_back(i);
      }
      if (!free.empty()) {
        const int M = static_cast<int>(free.size());
        Eigen::MatrixXd Qf(M, M);
        Eigen::VectorXd r(M);
        for (int a = 0; a < M; ++a) {
          r[a] = c[free[a]];
          for (int i = 0; i < N; ++i) {
            if (std::find(free.begin(), free.end(), i) == free.end()) {
              r[a] -= Q(free[a], i) * w[i];
            }
          }
          for (int b = 0; b < M; ++b) Qf(a, b) = Q(free[a], free[b]);
        }
        const Eigen::VectorXd wf = Qf.ldlt().solve(r);
        for (int a = 0; a < M; ++a) w[free[a]] = wf[a];
      }
      if (w.minCoeff() < -1e-12 || w.maxCoeff() > 1 + 1e-12) continue;
      best = std::min(best, Objective(Q, c, w));
    }
    const Eigen::VectorXd w = SolveBoundedBoxQp(Q, c, 100);
    EXPECT_GE(w.minCoeff(), 0.0);
    EXPECT_LE(w.maxCoeff(), 1.0);
    EXPECT_NEAR(Objective(Q, c, w), best, 1e-9 * (1 + std::abs(best)));
  }
}

// Blendshape-like problems: many strongly correlated shapes, a tiny
// Tikhonov term, weights beyond both bounds. The result satisfies the KKT
// conditions (w = clamp(w - g), g = Q w - c), with or without a warm start
// and through the fallback (a cold start allowed one primal-dual iteration
// only).
TEST_P(BoxQp, BoundedSatisfiesKktOnIllConditionedProblems) {
  std::mt19937 rng(GetParam());
  std::normal_distribution<double> g(0, 1);
  std::uniform_real_distribution<double> u(-0.6, 1.6);
  const int N = 60, R = 150;
  const Eigen::MatrixXd base = Eigen::MatrixXd::NullaryExpr(
      R, 12, [&](Eigen::Index, Eigen::Index) { return g(rng); });
  Eigen::MatrixXd mix = Eigen::MatrixXd::NullaryExpr(
      12, N, [&](Eigen::Index, Eigen::Index) { return g(rng); });
  const Eigen::MatrixXd A =
      base * mix + 0.05 * Eigen::MatrixXd::NullaryExpr(
                              R, N, [&](Eigen::Index, Eigen::Index) {
                                return g(rng);
                              });
  const Eigen::MatrixXd Q =
      A.transpose() * A + 1e-6 * Eigen::MatrixXd::Identity(N, N);
  auto kkt = [&](const Eigen::VectorXd& w, const Eigen::VectorXd& c) {
    const Eigen::VectorXd grad = Q * w - c;
    return ((w - grad).cwiseMax(0.0).cwiseMin(1.0) - w).lpNorm<Eigen::Infinity>();
  };
  for (int trial = 0; trial < 5; ++trial) {
    Eigen::VectorXd truth(N);
    for (int i = 0; i < N; ++i) truth[i] = u(rng);
    Eigen::VectorXd d = A * truth;
    for (int i = 0; i < R; ++i) d[i] += 0.3 * g(rng);
    const Eigen::VectorXd c = A.transpose() * d;
    const double tol = 1e-9 * (1 + c.lpNorm<Eigen::Infinity>());
    const Eigen::VectorXd cold = SolveBoundedBoxQp(Q, c, 100);
    Eigen::VectorXd guess(N);
    for (int i = 0; i < N; ++i) guess[i] = u(rng);
    const Eigen::VectorXd warm = SolveBoundedBoxQp(Q, c, 100, &guess);
    const Eigen::VectorXd fallback = SolveBoundedBoxQp(Q, c, 1);
    for (const Eigen::VectorXd* w : {&cold, &warm, &fallback}) {
      EXPECT_GE(w->minCoeff(), 0.0);
      EXPECT_LE(w->maxCoeff(), 1.0);
      EXPECT_LT(kkt(*w, c), tol) << "trial " << trial;
      // Strictly convex: one minimiser.
      EXPECT_NEAR(Objective(Q, c, *w), Objective(Q, c, cold),
                  1e-9 * (1 + std::abs(Objective(Q, c, cold))));
    }
    // The bounds matter here, or the test would not test them.
    const Eigen::VectorXd free = Q.llt().solve(c);
    EXPECT_TRUE(free.minCoeff() < 0 || free.maxCoeff() > 1);
  }
}

// The soft objective is C1 and convex: its minimum is where its gradient
// Q w - c + mu (min(w, 0) + max(w - 1, 0)) vanishes.
TEST_P(BoxQp, SoftReachesAStationaryPoint) {
  std::mt19937 rng(GetParam());
  std::normal_distribution<double> g(0, 1);
  const int N = 12;
  for (double mu : {0.0, 1.0, 100.0, 1e4}) {
    Eigen::MatrixXd A(20, N);
    for (int i = 0; i < A.size(); ++i) A.data()[i] = g(rng);
    const Eigen::MatrixXd Q = A.transpose() * A;
    Eigen::VectorXd c(N);
    for (int i = 0; i < N; ++i) c[i] = 5 * g(rng);
    const Eigen::VectorXd w = SolveSoftBoxQp(Q, c, mu, 100);
    const Eigen::VectorXd grad =
        Q * w - c + mu * (w.cwiseMin(0.0) + (w.array() - 1).max(0.0).matrix());
    EXPECT_LT(grad.norm(), 1e-8 * (1 + c.norm())) << "mu " << mu;
    // More penalty, closer to the box.
    if (mu > 0) {
      const Eigen::VectorXd unconstrained = Q.ldlt().solve(c);
      auto outside = [](const Eigen::VectorXd& x) {
        return (x.cwiseMin(0.0) + (x.array() - 1).max(0.0).matrix()).norm();
      };
      EXPECT_LE(outside(w), outside(unconstrained) + 1e-12);
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Seeds, BoxQp, ::testing::Values(1, 2, 3, 4));

class BlendshapeSeeded : public ::testing::TestWithParam<int> {};

TEST_P(BlendshapeSeeded, RecoversKnownWeightsInTheBox) {
  const int seed = GetParam();
  const Actor actor = SmallActor(seed, /*inbetweens=*/false);
  const ShapeData data = ComputeShapeData(actor);
  ASSERT_GT(3 * data.num_bundles, data.num_shapes);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  Eigen::VectorXd truth(data.num_shapes);
  for (int n = 0; n < truth.size(); ++n) truth[n] = u(rng) < 0.3 ? 0 : u(rng);
  JawPose jaw;
  jaw.open_deg = 8 * u(rng);
  jaw.lateral_deg = u(rng) - 0.5;
  const BundleFrame frame = BundlesOf(data, truth, jaw, 1);
  const MatX3d expected = [&] {
    MatX3d x = actor.neutral.V;
    for (int v = 0; v < data.num_vertices; ++v) {
      for (int n = 0; n < data.num_shapes; ++n) {
        const float* d = data.Displacement(v, n);
        for (int a = 0; d && a < 3; ++a) x(v, a) += truth[n] * d[a];
      }
    }
    return data.jaw_rig ? Skin(*data.jaw_rig, jaw, x) : x;
  }();
  for (bool bounded : {false, true}) {
    BlendshapeOptions options;
    options.bounded = bounded;
    options.tikhonov = 1e-12;  // exact recovery needs no bias
    const BlendshapeSolver solver(actor.neutral, data, options);
    Eigen::VectorXd w;
    MatX3d mesh;
    const FrameSolve fs = solver.SolveFrame(frame, jaw, &w, &mesh);
    ASSERT_TRUE(fs.ok) << fs.reason;
    EXPECT_LT((w - truth).lpNorm<Eigen::Infinity>(), 1e-6)
        << "bounded " << bounded;
    EXPECT_LT((mesh - expected).cwiseAbs().maxCoeff(), 1e-5);
    // The residual is the skinned truth's own: skinning a surface point of
    // a deformed triangle is not exactly skinning its vertices
    // (indexing/shape_data.h).
    for (int k = 0; k < data.num_bundles; ++k) {
      const double own =
          (EvaluateSurfacePoint(data.sites[k], actor.neutral.F, expected) -
           frame.bundles.at(data.bundle_names[k]))
              .norm();
      EXPECT_NEAR(fs.bundles[k].residual, own, 1e-5);
    }
  }
}

TEST_P(BlendshapeSeeded, BoundedStaysInTheBoxAndSoftIsPulledTowardIt) {
  const int seed = GetParam();
  const Actor actor = SmallActor(seed, /*inbetweens=*/true);
  const ShapeData data = ComputeShapeData(actor);
  std::mt19937 rng(seed + 100);
  std::uniform_real_distribution<double> u(-0.8, 1.8);
  Eigen::VectorXd truth(data.num_shapes);
  for (int n = 0; n < truth.size(); ++n) truth[n] = u(rng);
  BundleFrame frame = BundlesOf(data, truth, JawPose(), 3);
  // A few markers missing.
  for (int k = 0; k < data.num_bundles; k += 7) {
    frame.bundles.erase(data.bundle_names[k]);
  }
  BlendshapeOptions soft_options, hard_options;
  hard_options.bounded = true;
  Eigen::VectorXd soft, hard;
  ASSERT_TRUE(BlendshapeSolver(actor.neutral, data, soft_options)
                  .SolveFrame(frame, JawPose(), &soft, nullptr)
                  .ok);
  ASSERT_TRUE(BlendshapeSolver(actor.neutral, data, hard_options)
                  .SolveFrame(frame, JawPose(), &hard, nullptr)
                  .ok);
  EXPECT_GE(hard.minCoeff(), 0.0);
  EXPECT_LE(hard.maxCoeff(), 1.0);
  auto outside = [](const Eigen::VectorXd& x) {
    return (x.cwiseMin(0.0) + (x.array() - 1).max(0.0).matrix()).norm();
  };
  EXPECT_LT(outside(soft), outside(truth));
}

TEST_P(BlendshapeSeeded, SequenceFlagsBadFramesAndKeepsTheLastGoodMesh) {
  const int seed = GetParam();
  const Actor actor = SmallActor(seed, /*inbetweens=*/false);
  const ShapeData data = ComputeShapeData(actor);
  Eigen::VectorXd w = Eigen::VectorXd::Constant(data.num_shapes, 0.2);
  std::vector<BundleFrame> frames = {BundlesOf(data, w, JawPose(), 1),
                                     BundlesOf(data, w, JawPose(), 2),
                                     BundlesOf(data, 2 * w, JawPose(), 3)};
  // Frame 2 keeps only two markers: too few.
  while (frames[1].bundles.size() > 2) {
    frames[1].bundles.erase(frames[1].bundles.begin());
  }
  const BlendshapeSolver solver(actor.neutral, data, BlendshapeOptions());
  std::vector<Eigen::VectorXd> weights;
  const SolveResult r = solver.SolveSequence(frames, {}, {}, &weights);
  ASSERT_EQ(r.meshes.size(), 3u);
  EXPECT_TRUE(r.frames[0].ok);
  EXPECT_FALSE(r.frames[1].ok);
  EXPECT_FALSE(r.frames[1].reason.empty());
  EXPECT_TRUE(r.frames[2].ok);
  EXPECT_EQ(r.summary.bad_frames, 1);
  EXPECT_EQ((r.meshes[1] - r.meshes[0]).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_GT((r.meshes[2] - r.meshes[0]).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ(weights[1].size(), 0);
  EXPECT_EQ(weights[2].size(), data.num_shapes);
}

// The leave-one-out residuals against refitting without each bundle, with
// the bounds the full fit found active held (weights outside the box and
// noise make some active; a few markers are missing; ridges differ per
// shape).
TEST_P(BlendshapeSeeded, LeaveOneOutMatchesRefitting) {
  const int seed = GetParam();
  const Actor actor = SmallActor(seed, /*inbetweens=*/false);
  const ShapeData data = ComputeShapeData(actor);
  const int K = data.num_bundles, N = data.num_shapes;
  std::mt19937 rng(seed + 300);
  std::uniform_real_distribution<double> u(-0.3, 1.3), r(0.01, 2.0);
  std::normal_distribution<double> noise(0.0, 0.2);
  Eigen::MatrixXd B(3 * K, N);  // B_k = the shapes at bundle k's site
  for (int k = 0; k < K; ++k) {
    for (int n = 0; n < N; ++n) B.block<3, 1>(3 * k, n) = data.SiteDisplacement(n, k);
  }
  Eigen::VectorXd truth(N), ridge(N);
  for (int n = 0; n < N; ++n) {
    truth[n] = u(rng);
    ridge[n] = r(rng);
  }
  std::vector<char> observed(K, 1);
  for (int k = 0; k < K; k += 9) observed[k] = 0;
  Eigen::VectorXd d = B * truth;
  for (int k = 0; k < K; ++k) {
    for (int c = 0; c < 3; ++c) {
      d[3 * k + c] = observed[k] ? d[3 * k + c] + noise(rng) : 0.0;
    }
  }
  BlendshapeOptions options;
  options.bounded = true;
  const BlendshapeSolver solver(actor.neutral, data, options);
  const Eigen::VectorXd w = solver.FitWeights(observed, d, ridge);
  std::vector<int> free, active;
  for (int n = 0; n < N; ++n) (w[n] > 0 && w[n] < 1 ? free : active).push_back(n);
  ASSERT_FALSE(active.empty());
  ASSERT_GT(free.size(), 3u);
  std::vector<Vec3> residual(K, Vec3::Zero());
  for (int k = 0; k < K; ++k) {
    if (observed[k]) residual[k] = d.segment<3>(3 * k) - B.middleRows<3>(3 * k) * w;
  }
  const std::vector<Vec3> loo =
      solver.LeaveOneOutResiduals(observed, w, ridge, residual);
  int checked = 0;
  double worst = 0, largest = 0;
  for (int left = 0; left < K; ++left) {
    if (!observed[left]) {
      EXPECT_EQ(loo[left].norm(), 0.0);
      continue;
    }
    // min |B_F w_F - (d - B_A w_A)|^2 + (tikhonov + ridge) |w_F|^2 over
    // the other observed bundles.
    const int F = static_cast<int>(free.size());
    Eigen::MatrixXd normal = Eigen::MatrixXd::Zero(F, F);
    Eigen::VectorXd rhs = Eigen::VectorXd::Zero(F);
    for (int k = 0; k < K; ++k) {
      if (!observed[k] || k == left) continue;
      Eigen::MatrixXd bf(3, F);
      for (int a = 0; a < F; ++a) bf.col(a) = B.block<3, 1>(3 * k, free[a]);
      Vec3 target = d.segment<3>(3 * k);
      for (int n : active) target -= w[n] * B.block<3, 1>(3 * k, n);
      normal += bf.transpose() * bf;
      rhs += bf.transpose() * target;
    }
    for (int a = 0; a < F; ++a) normal(a, a) += options.tikhonov + ridge[free[a]];
    const Eigen::VectorXd wf = normal.ldlt().solve(rhs);
    Eigen::VectorXd refit = w;
    for (int a = 0; a < F; ++a) refit[free[a]] = wf[a];
    const Vec3 expected =
        d.segment<3>(3 * left) - B.middleRows<3>(3 * left) * refit;
    worst = std::max(worst, (loo[left] - expected).norm());
    largest = std::max(largest, expected.norm());
    ++checked;
  }
  EXPECT_GT(checked, K / 2);
  EXPECT_LT(worst, 1e-7 * (1 + largest));
  // The prediction misses by more than the fit: the check can fail.
  double in_fit = 0, left_out = 0;
  for (int k = 0; k < K; ++k) {
    in_fit += residual[k].squaredNorm();
    left_out += loo[k].squaredNorm();
  }
  EXPECT_GT(left_out, in_fit);
}

// The spanning selection (a global fit of bounded size): every shape when
// the cap allows; else the shapes, in order, that add a direction at the
// bundles -- combinations of earlier ones and still shapes never -- and
// every shape lies within the threshold of the kept shapes' span.
TEST_P(BlendshapeSeeded, SpanningShapesCoverTheDataset) {
  std::mt19937 rng(GetParam());
  std::normal_distribution<double> g(0, 1);
  std::uniform_real_distribution<double> u(0, 1);
  const int rows = 60, base = 12, combos = 25, fresh = 8;
  const double min_new = 0.05;
  Eigen::MatrixXd B(rows, base + combos + 1 + fresh);
  for (int n = 0; n < base; ++n) {
    for (int r = 0; r < rows; ++r) B(r, n) = g(rng);
  }
  // Combinations of the base shapes, a little off their span (below the
  // threshold), then a shape that does not move the bundles, then new ones.
  for (int n = base; n < base + combos; ++n) {
    B.col(n).setZero();
    for (int m = 0; m < base; ++m) {
      if (u(rng) < 0.3) B.col(n) += u(rng) * B.col(m);
    }
    B.col(n) += 0.2 * B.col(static_cast<int>(u(rng) * base));
    Eigen::VectorXd off(rows);
    for (int r = 0; r < rows; ++r) off[r] = g(rng);
    B.col(n) += 0.2 * min_new * B.col(n).norm() / off.norm() * off;
  }
  B.col(base + combos).setZero();
  for (int n = base + combos + 1; n < B.cols(); ++n) {
    for (int r = 0; r < rows; ++r) B(r, n) = g(rng);
  }
  const int N = static_cast<int>(B.cols());
  for (int cap : {0, N, N + 5}) {
    const std::vector<int> all = SelectSpanningShapes(B, cap, min_new);
    ASSERT_EQ(static_cast<int>(all.size()), N);
    for (int n = 0; n < N; ++n) EXPECT_EQ(all[n], n);
  }
  for (int cap : {N - 1, base + 3, base / 2}) {
    const std::vector<int> kept = SelectSpanningShapes(B, cap, min_new);
    ASSERT_LE(static_cast<int>(kept.size()), cap);
    ASSERT_TRUE(std::is_sorted(kept.begin(), kept.end()));
    for (int n : kept) EXPECT_TRUE(n < base || n > base + combos) << n;
    // In order: the first shapes of the base come first.
    for (int i = 0; i < std::min(cap, base); ++i) EXPECT_EQ(kept[i], i);
    if (static_cast<int>(kept.size()) == cap) continue;  // the cap cut it
    ASSERT_EQ(static_cast<int>(kept.size()), base + fresh);
    Eigen::MatrixXd K(rows, kept.size());
    for (size_t i = 0; i < kept.size(); ++i) K.col(static_cast<int>(i)) = B.col(kept[i]);
    const Eigen::MatrixXd P = K * K.colPivHouseholderQr().solve(B);
    for (int n = 0; n < N; ++n) {
      EXPECT_LE((B.col(n) - P.col(n)).norm(), min_new * B.col(n).norm() + 1e-12) << n;
    }
  }
}

// A fit over a bounded set of shapes recovers blends of its shapes, and its
// mesh is the blend of those dataset shapes.
TEST_P(BlendshapeSeeded, BoundedShapeSetRecoversBlendsOfItsShapes) {
  const int seed = GetParam();
  const Actor actor = SmallActor(seed, /*inbetweens=*/true);
  const ShapeData data = ComputeShapeData(actor);
  BlendshapeOptions options;
  options.bounded = true;
  options.tikhonov = 1e-12;
  options.max_shapes = data.num_shapes / 2;
  const BlendshapeSolver solver(actor.neutral, data, options);
  ASSERT_GT(solver.num_shapes(), 0);
  ASSERT_LE(solver.num_shapes(), options.max_shapes);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  Eigen::VectorXd truth = Eigen::VectorXd::Zero(data.num_shapes);
  Eigen::VectorXd own(solver.num_shapes());
  for (int i = 0; i < solver.num_shapes(); ++i) {
    own[i] = u(rng) < 0.5 ? 0 : u(rng);
    truth[solver.shapes()[i]] = own[i];
  }
  const JawPose jaw;
  const BundleFrame frame = BundlesOf(data, truth, jaw, 1);
  Eigen::VectorXd w;
  MatX3d mesh;
  const FrameSolve fs = solver.SolveFrame(frame, jaw, &w, &mesh);
  ASSERT_TRUE(fs.ok) << fs.reason;
  EXPECT_LT((w - own).lpNorm<Eigen::Infinity>(), 1e-6);
  MatX3d expected = actor.neutral.V;
  for (int v = 0; v < data.num_vertices; ++v) {
    for (int n = 0; n < data.num_shapes; ++n) {
      const float* d = data.Displacement(v, n);
      for (int a = 0; d && a < 3; ++a) expected(v, a) += truth[n] * d[a];
    }
  }
  if (data.jaw_rig) expected = Skin(*data.jaw_rig, jaw, expected);
  EXPECT_LT((mesh - expected).cwiseAbs().maxCoeff(), 1e-5);
}

INSTANTIATE_TEST_SUITE_P(Seeds, BlendshapeSeeded, ::testing::Values(1, 2, 5));

}  // namespace
}  // namespace hmc
