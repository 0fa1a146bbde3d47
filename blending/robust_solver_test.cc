#include "blending/robust_solver.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <numeric>
#include <random>

#include "blending/small_lgi_test_util.h"
#include "core/jaw.h"
#include "blending/thread_count_test_util.h"

namespace hmc {
namespace {

BlendshapeOptions Bounded() {
  BlendshapeOptions o;
  o.bounded = true;
  return o;
}

// A small actor with its real lgi model and the bounded global fit.
struct RobustFixture : SmallLgiModel {
  explicit RobustFixture(int seed, bool jaw, RobustOptions options = {},
                         BlendshapeOptions global_options = Bounded())
      : SmallLgiModel(seed, jaw),
        global(actor.neutral, model.data, global_options),
        robust(actor.neutral, model.data, lgi, model.nn, global,
               SolveOptions(), options) {}

  BlendshapeSolver global;
  RobustSolver robust;
  RobustReport report;  // of the last robust solve
};

// Mean vertex error of a solve against the truth meshes (mm).
double MeanError(const SolveResult& result, const std::vector<MatX3d>& truth) {
  double sum = 0;
  int64_t count = 0;
  for (size_t f = 0; f < truth.size(); ++f) {
    sum += (result.meshes[f] - truth[f]).rowwise().norm().sum();
    count += truth[f].rows();
  }
  return sum / count;
}

// The largest distance between an observed bundle and the surface (mm).
double WorstBundleResidual(const SolveResult& result) {
  double worst = 0;
  for (const FrameSolve& frame : result.frames) {
    for (const BundleSolve& b : frame.bundles) worst = std::max(worst, b.residual);
  }
  return worst;
}

class RobustSeeds : public ::testing::TestWithParam<int> {};

// Verification stays exact: every dataset shape, noise-free, with and
// without a jaw rig, reconstructs everywhere (not only at the bundles), and
// the noise estimated from such data is ~0.
// With the global fit over fewer shapes than the dataset's (a bounded
// global fit, robust.global_shapes) the local answer still reconstructs the
// shapes the global fit lacks.
TEST_P(RobustSeeds, DatasetShapesReconstructExactly) {
  for (int global_shapes : {0, 5}) {
  for (bool jaw : {false, true}) {
    SCOPED_TRACE(::testing::Message() << "jaw " << jaw << ", global_shapes "
                                      << global_shapes);
    BlendshapeOptions global = Bounded();
    global.max_shapes = global_shapes;
    RobustFixture fx(GetParam(), jaw, {}, global);
    if (global_shapes > 0) {
      ASSERT_LE(fx.global.num_shapes(), global_shapes);
      ASSERT_LT(fx.global.num_shapes(), static_cast<int>(fx.actor.shapes.size()));
    }
    std::mt19937 rng(GetParam());
    std::vector<BundleFrame> frames;
    std::vector<MatX3d> truth;
    std::vector<JawPose> poses;
    for (size_t n = 0; n < fx.actor.shapes.size(); ++n) {
      truth.push_back(fx.actor.ShapePositions(static_cast<int>(n)));
      frames.push_back(
          fx.Bundles(static_cast<int>(n) + 1, truth.back(), 0.0, &rng));
      poses.push_back(fx.actor.shapes[n].jaw);
    }
    const SolveResult result =
        fx.robust.SolveSequence(frames, jaw ? poses : std::vector<JawPose>{}, {}, &fx.report);
    double worst = 0;
    for (size_t f = 0; f < truth.size(); ++f) {
      ASSERT_TRUE(result.frames[f].ok) << result.frames[f].reason;
      worst = std::max(worst,
                       (result.meshes[f] - truth[f]).rowwise().norm().maxCoeff());
    }
    EXPECT_LE(worst, 1e-3);
    // The estimate reads the global fit's misfit as noise: of the shapes it
    // lacks too (0.02-0.11 mm here, 7 of 12 independent shapes left out).
    if (global_shapes == 0) {
      EXPECT_LT(fx.report.noise_mm, 1e-3);
    }
    EXPECT_TRUE(fx.report.noise_estimated);
    EXPECT_EQ(fx.report.global_shapes, fx.global.num_shapes());
  }
  }
}

// Under marker noise the estimate finds its level and the robust solve is
// more accurate than the paper's lgi, which passes through every noisy
// bundle. It is not asserted to beat the bounded global fit here: on this
// small actor (12 shapes, random two-shape mixtures, so every shape is
// used) it does not on seed 2 (docs/method.md, "The robust default", gives
// the numbers).
TEST_P(RobustSeeds, NoisyMarkersAreAveragedNotFollowed) {
  RobustFixture fx(GetParam(), /*jaw=*/false);
  std::mt19937 rng(500 + GetParam());
  std::uniform_int_distribution<int> pick(
      0, static_cast<int>(fx.actor.shapes.size()) - 1);
  std::uniform_real_distribution<double> t(0.2, 0.8);
  const double sigma = 0.3;
  std::vector<BundleFrame> frames;
  std::vector<MatX3d> truth;
  for (int f = 0; f < 12; ++f) {
    const int a = pick(rng), b = pick(rng);
    const double s = t(rng);
    truth.push_back(fx.actor.neutral.V +
                    s * fx.actor.shapes[a].displacement +
                    (1 - s) * fx.actor.shapes[b].displacement);
    frames.push_back(fx.Bundles(f + 1, truth.back(), sigma, &rng));
  }
  const SolveResult robust = fx.robust.SolveSequence(frames, {}, {}, &fx.report);
  EXPECT_NEAR(fx.report.noise_mm, sigma, 0.25 * sigma);
  EXPECT_GT(fx.report.ridge, 0.0);
  const double e_robust = MeanError(robust, truth);
  const double e_lgi = MeanError(fx.lgi.SolveSequence(frames, {}), truth);
  const double e_global = MeanError(fx.global.SolveSequence(frames, {}), truth);
  EXPECT_LT(e_robust, e_lgi);
  std::printf("seed %d: mean error robust %.4f, lgi %.4f, bounded %.4f mm\n",
              GetParam(), e_robust, e_lgi, e_global);
  // A given noise level is used as given.
  RobustOptions given;
  given.noise_mm = sigma;
  RobustFixture fixed(GetParam(), /*jaw=*/false, given);
  fixed.robust.SolveSequence(frames, {}, {}, &fixed.report);
  EXPECT_EQ(fixed.report.noise_mm, sigma);
  EXPECT_FALSE(fixed.report.noise_estimated);
}

// A sequence that uses a few shapes (a performance): the evidence gives every
// shape it uses a smaller ridge than the typical (median) shape it does not
// use, and the solve is then more accurate than the bounded fit, against
// ground truth. (The ratio median unused / largest used was 50, 68 and 4.7
// on seeds 1-3: a margin of 10 failed on seed 3, where some unused shapes
// resemble used ones enough to stand in for them and keep small ridges.)
TEST_P(RobustSeeds, ShapesTheSequenceDoesNotUseAreHeldBack) {
  RobustFixture fx(GetParam(), /*jaw=*/false);
  std::mt19937 rng(700 + GetParam());
  const int N = static_cast<int>(fx.actor.shapes.size());
  std::vector<int> order(N);
  std::iota(order.begin(), order.end(), 0);
  std::shuffle(order.begin(), order.end(), rng);
  const std::vector<int> used(order.begin(), order.begin() + 3);
  std::uniform_real_distribution<double> weight(0.1, 0.9);
  const double sigma = 0.3;
  std::vector<BundleFrame> frames;
  std::vector<MatX3d> truth;
  for (int f = 0; f < 16; ++f) {
    MatX3d x = fx.actor.neutral.V;
    for (int n : used) x += weight(rng) * fx.actor.shapes[n].displacement;
    truth.push_back(x);
    frames.push_back(fx.Bundles(f + 1, x, sigma, &rng));
  }
  const SolveResult robust = fx.robust.SolveSequence(frames, {}, {}, &fx.report);
  const std::vector<double>& ridge = fx.report.shape_ridge;
  ASSERT_EQ(static_cast<int>(ridge.size()), N);
  double used_max = 0;
  std::vector<double> unused;
  for (int n = 0; n < N; ++n) {
    if (std::find(used.begin(), used.end(), n) != used.end()) {
      used_max = std::max(used_max, ridge[n]);
    } else {
      unused.push_back(ridge[n]);
    }
  }
  std::sort(unused.begin(), unused.end());
  const double unused_median = unused[unused.size() / 2];
  EXPECT_GT(unused_median, used_max);
  const double e_robust = MeanError(robust, truth);
  const double e_global = MeanError(fx.global.SolveSequence(frames, {}), truth);
  EXPECT_LT(e_robust, e_global);
  std::printf(
      "seed %d: %d shapes; ridge used <= %.3g, unused median %.3g (min %.3g); "
      "mean error robust %.4f, bounded %.4f mm\n",
      GetParam(), N, used_max, unused_median, unused.front(), e_robust,
      e_global);
}

TEST_P(RobustSeeds, BadFrameRepeatsThePreviousGoodMesh) {
  RobustFixture fx(GetParam(), /*jaw=*/false);
  std::mt19937 rng(600 + GetParam());
  std::vector<BundleFrame> frames;
  for (int f = 0; f < 3; ++f) {
    frames.push_back(fx.Bundles(
        f + 1, fx.actor.ShapePositions(f % fx.actor.shapes.size()), 0.0, &rng));
  }
  frames[2].bundles.clear();  // nothing observed: bad
  const SolveResult result =
      fx.robust.SolveSequence(frames, {}, {"", "tracking lost", ""}, &fx.report);
  ASSERT_TRUE(result.frames[0].ok);
  EXPECT_FALSE(result.frames[1].ok);
  EXPECT_EQ(result.frames[1].reason, "tracking lost");
  EXPECT_FALSE(result.frames[2].ok);
  EXPECT_EQ(result.summary.bad_frames, 2);
  EXPECT_EQ((result.meshes[1] - result.meshes[0]).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ((result.meshes[2] - result.meshes[0]).cwiseAbs().maxCoeff(), 0.0);
}

// Streamed to a sink (issue 46: a long take's meshes are written as they
// are blended), the solve hands over every frame once, in order, with the
// bytes of the held solve: over several blend batches, with a jaw rig, a
// bad first frame (the skinned neutral) and bad frames later (the previous
// good mesh); the result then holds no mesh and the same records.
TEST_P(RobustSeeds, SinkGetsTheHeldMeshesInOrder) {
  RobustFixture fx(GetParam(), /*jaw=*/true);
  std::mt19937 rng(700 + GetParam());
  const int F = 21;  // three batches of kBlendBatch (8), the last short
  std::vector<BundleFrame> frames;
  std::vector<JawPose> poses;
  std::vector<std::string> errors(F);
  for (int f = 0; f < F; ++f) {
    const int n = f % static_cast<int>(fx.actor.shapes.size());
    frames.push_back(fx.Bundles(f + 1, fx.actor.ShapePositions(n), 0.05, &rng));
    poses.push_back(fx.actor.shapes[n].jaw);
  }
  errors[0] = errors[9] = errors[10] = "tracking lost";
  const SolveResult held = fx.robust.SolveSequence(frames, poses, errors);
  std::vector<int> order;
  std::vector<MatX3d> streamed;
  const MeshSink sink = [&](int f, const FrameSolve& frame, const MatX3d& mesh) {
    EXPECT_EQ(frame.frame, f + 1);
    order.push_back(f);
    streamed.push_back(mesh);
  };
  const SolveResult result = fx.robust.SolveSequence(frames, poses, errors, nullptr, &sink);
  EXPECT_TRUE(result.meshes.empty());
  ASSERT_EQ(order.size(), static_cast<size_t>(F));
  for (int f = 0; f < F; ++f) {
    EXPECT_EQ(order[f], f);
    EXPECT_TRUE(streamed[f] == held.meshes[f]) << "frame " << f;
    EXPECT_EQ(result.frames[f].ok, held.frames[f].ok);
    for (size_t k = 0; k < held.frames[f].bundles.size(); ++k) {
      EXPECT_EQ(result.frames[f].bundles[k].residual, held.frames[f].bundles[k].residual);
    }
  }
  EXPECT_EQ(result.summary.bad_frames, 3);
  EXPECT_EQ(held.summary.bad_frames, 3);
  EXPECT_TRUE(streamed[0] == MatX3d(Skin(*fx.actor.jaw_rig, poses[0], fx.actor.neutral.V)));
  EXPECT_TRUE(streamed[10] == streamed[8]);
}

// The shape prior's noise (the evidence's, floored by the choice's noise).
// Noise-free combinations of dataset shapes with a small nonlinear part (as
// combinations of facial action units have): it stays at the misfit's level,
// microns, and the solve beats the bounded fit against ground truth. Under
// 0.3 mm marker noise it is the noise level. (On this small actor the
// evidence alone already gets both right; on the default synthetic actor it
// put 0.5 mm noise at 0.37 mm, which the floor corrects: docs/method.md.)
TEST_P(RobustSeeds, ThePriorsNoiseIsTheMarkerNoise) {
  for (double sigma : {0.0, 0.3}) {
    SCOPED_TRACE(sigma);
    RobustFixture fx(GetParam(), /*jaw=*/false);
    std::mt19937 rng(900 + GetParam());
    const int N = static_cast<int>(fx.actor.shapes.size());
    std::uniform_int_distribution<int> shape(0, N - 1);
    std::uniform_real_distribution<double> weight(0.1, 0.9);
    std::vector<BundleFrame> frames;
    std::vector<MatX3d> truth;
    for (int f = 0; f < 16; ++f) {
      const int a = shape(rng), b = (a + 1 + shape(rng) % (N - 1)) % N;
      const double wa = weight(rng), wb = weight(rng);
      const MatX3d& da = fx.actor.shapes[a].displacement;
      const MatX3d& db = fx.actor.shapes[b].displacement;
      // The nonlinear part: 5 % of the pair's product, per coordinate.
      truth.push_back(fx.actor.neutral.V + wa * da + wb * db +
                      0.05 * wa * wb * da.cwiseProduct(db));
      frames.push_back(fx.Bundles(f + 1, truth.back(), sigma, &rng));
    }
    const SolveResult robust = fx.robust.SolveSequence(frames, {}, {}, &fx.report);
    const RobustReport& report = fx.report;
    const double e_robust = MeanError(robust, truth);
    const double e_global =
        MeanError(fx.global.SolveSequence(frames, {}), truth);
    std::printf(
        "seed %d, noise %.1f mm: noise estimated %.2g mm, prior's %.2g mm; "
        "mean error robust %.5f, bounded %.5f mm\n",
        GetParam(), sigma, report.noise_mm, report.prior_noise_mm, e_robust,
        e_global);
    if (sigma == 0) {
      EXPECT_LT(report.prior_noise_mm, 0.01);
      EXPECT_LT(e_robust, e_global);
    } else {
      EXPECT_NEAR(report.prior_noise_mm, sigma, 0.2 * sigma);
    }
  }
}

// Step 5's interpolation, noise-free: what the kernel leaves at the
// bundles beyond the threshold is carried to the surface, so the surface
// comes back to within the threshold of every bundle. (On this small actor
// the kernel already brings the face within ~0.005 mm of the truth, and the
// mean error moves by < 3 %; the experiment's held-out rows are where it
// counts, docs/method.md.)
TEST_P(RobustSeeds, NoiseFreeBundlesAreReachedAgain) {
  RobustOptions without;
  without.interpolate = false;
  RobustFixture fx(GetParam(), /*jaw=*/false), fx_without(GetParam(), false, without);
  std::mt19937 rng(900 + GetParam());
  std::uniform_real_distribution<double> scale(1.2, 1.6);
  std::vector<BundleFrame> frames;
  std::vector<MatX3d> truth;
  for (size_t n = 0; n < fx.actor.shapes.size(); ++n) {
    truth.push_back(fx.actor.neutral.V +
                    scale(rng) * fx.actor.shapes[n].displacement);
    frames.push_back(fx.Bundles(static_cast<int>(n) + 1, truth.back(), 0.0, &rng));
  }
  const SolveResult with = fx.robust.SolveSequence(frames, {}, {}, &fx.report);
  const SolveResult plain = fx_without.robust.SolveSequence(frames, {}, {}, &fx_without.report);
  EXPECT_GT(fx.report.bundles_interpolated, 0);
  EXPECT_EQ(fx_without.report.bundles_interpolated, 0);
  const double worst_with = WorstBundleResidual(with);
  const double worst_plain = WorstBundleResidual(plain);
  const double e_with = MeanError(with, truth), e_plain = MeanError(plain, truth);
  const double tau = fx.report.threshold_mm;
  std::printf("seed %d: interpolated %.4f, not %.4f mm mean error; worst "
              "bundle residual %.4f, %.4f mm (threshold %.4f mm)\n",
              GetParam(), e_with, e_plain, worst_with, worst_plain, tau);
  // Left: the threshold (the offset is soft-thresholded), and the part of
  // the offset the site's triangle does not carry (its vertices' weights
  // on the bundle are not quite 1).
  EXPECT_LT(worst_with, tau + 0.2 * worst_plain);
  EXPECT_GT(worst_plain, tau + 0.2 * worst_plain);  // the check can fail
}

// Expressions beyond the dataset (shapes exaggerated 1.4x: the bundles fall
// outside their clouds and lgi projects them), noise-free: robust takes the
// surface to the bundles, where lgi leaves the projection's error. (Here
// the global fit does most of it: a shape and its in-between reach 1.4x
// within the bounds. The correction is chosen on seed 3 only; on seeds 1
// and 2 C_p prefers none.)
TEST_P(RobustSeeds, ExpressionsBeyondTheDataAreCorrected) {
  RobustFixture fx(GetParam(), /*jaw=*/false);
  std::mt19937 rng(800 + GetParam());
  std::vector<BundleFrame> frames;
  std::vector<MatX3d> truth;
  for (size_t n = 0; n < fx.actor.shapes.size(); ++n) {
    truth.push_back(fx.actor.neutral.V + 1.4 * fx.actor.shapes[n].displacement);
    frames.push_back(fx.Bundles(static_cast<int>(n) + 1, truth.back(), 0.0, &rng));
  }
  const SolveResult robust = fx.robust.SolveSequence(frames, {}, {}, &fx.report);
  const SolveResult lgi = fx.lgi.SolveSequence(frames, {});
  EXPECT_GT(lgi.summary.bundles_projected, 0);
  // ~0 against the noise levels that matter (0.1-1 mm).
  EXPECT_LT(fx.report.selection_noise_mm, 0.01);
  const double worst_robust = WorstBundleResidual(robust);
  const double worst_lgi = WorstBundleResidual(lgi);
  EXPECT_LT(worst_robust, 0.5 * worst_lgi);
  const double e_robust = MeanError(robust, truth), e_lgi = MeanError(lgi, truth);
  std::printf("seed %d: beyond the data, mean error robust %.4f, lgi %.4f mm; "
              "worst bundle residual %.4f, %.4f mm\n",
              GetParam(), e_robust, e_lgi, worst_robust, worst_lgi);
  EXPECT_LT(e_robust, e_lgi);
}

TEST_P(RobustSeeds, SameResultForAnyThreadCount) {
  RobustFixture fx(GetParam(), /*jaw=*/true);
  std::mt19937 rng(700 + GetParam());
  std::vector<BundleFrame> frames;
  for (int f = 0; f < 3; ++f) {
    frames.push_back(fx.Bundles(
        f + 1, fx.actor.ShapePositions(f % fx.actor.shapes.size()), 0.2, &rng));
  }
  ExpectSameMeshesForAnyThreadCount(
      [&] { return fx.robust.SolveSequence(frames, {}, {}, &fx.report); });
}

// A slow take (two shapes blended back and forth over 40 frames) is told
// from unrelated frames, and on it the correction measures how much of the
// residuals' noise averaging over frames removes: most of independent
// noise, little of an error that stays the same for stretches of frames
// (as a tracked dot's biased centroid does), which the correction must not
// then fit as signal.
TEST_P(RobustSeeds, OnATakeTheCorrectionMeasuresTheNoiseAveragingRemoves) {
  RobustFixture fx(GetParam(), /*jaw=*/false);
  const int F = 40;
  const int a = GetParam() % static_cast<int>(fx.actor.shapes.size());
  const int b = (GetParam() + 5) % static_cast<int>(fx.actor.shapes.size());
  std::vector<MatX3d> truth;
  for (int f = 0; f < F; ++f) {
    const double s = 0.5 + 0.4 * std::sin(2 * M_PI * f / 30.0);
    truth.push_back(fx.actor.neutral.V + s * fx.actor.shapes[a].displacement +
                    (1 - s) * 0.6 * fx.actor.shapes[b].displacement);
  }
  auto solve = [&](bool persistent) {
    std::mt19937 rng(700 + GetParam());
    std::normal_distribution<double> n(0.0, 0.3);
    std::map<std::string, Vec3> offset;
    std::vector<BundleFrame> frames;
    for (int f = 0; f < F; ++f) {
      BundleFrame frame = fx.Bundles(f + 1, truth[f]);
      for (auto& [name, p] : frame.bundles) {
        // Persistent: one error per bundle for each stretch of 10 frames.
        if (!persistent || f % 10 == 0 || !offset.count(name)) {
          offset[name] = Vec3(n(rng), n(rng), n(rng));
        }
        p += offset[name];
      }
      frames.push_back(frame);
    }
    const SolveResult result = fx.robust.SolveSequence(frames, {}, {}, &fx.report);
    EXPECT_TRUE(fx.report.take) << fx.report.take_correlation;
    return fx.report.correction_noise_kept;
  };
  const double independent = solve(false), persistent = solve(true);
  std::printf("seed %d: noise variance kept by the average: independent %.3f, persistent %.3f\n",
              GetParam(), independent, persistent);
  EXPECT_LT(independent, 0.5);
  EXPECT_GT(persistent, 0.7);
}

INSTANTIATE_TEST_SUITE_P(Seeds, RobustSeeds, ::testing::Values(1, 2, 3));

}  // namespace
}  // namespace hmc
