#include "blending/temporal_coherence.h"

#include <cmath>
#include <map>
#include <random>

#include <gtest/gtest.h>

#include "blending/frame_solve.h"
#include "indexing/lgi_test_actor.h"

namespace hmc {
namespace {

// Per bundle, the observed displacement sum_n w_n b*_n(s_k) + noise, and
// the answer `answer` (one weight vector for every bundle).
struct Sequence {
  std::vector<std::vector<std::vector<std::pair<int, double>>>> weights;
  std::vector<std::vector<Vec3>> disp;
  std::vector<std::vector<char>> observed;
  std::vector<TemporalFrame> frames;
  std::vector<int> numbers;
};

Sequence Make(const ShapeData& data,
              const std::vector<Eigen::VectorXd>& truth,
              const std::vector<Eigen::VectorXd>& answer, double noise,
              int seed) {
  const int F = static_cast<int>(truth.size()), K = data.num_bundles;
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0.0, 1.0);
  Sequence s;
  s.weights.resize(F);
  s.disp.resize(F);
  s.observed.assign(F, std::vector<char>(K, 1));
  for (int f = 0; f < F; ++f) {
    s.weights[f].resize(K);
    s.disp[f].resize(K);
    for (int k = 0; k < K; ++k) {
      Vec3 d = Vec3::Zero();
      for (int i = 0; i < truth[f].size(); ++i) {
        d += truth[f][i] * data.SiteDisplacement(i, k);
        if (answer[f][i] != 0) s.weights[f][k].emplace_back(i, answer[f][i]);
      }
      s.disp[f][k] = d + noise * Vec3(n(rng), n(rng), n(rng));
    }
    s.numbers.push_back(f);
  }
  for (int f = 0; f < F; ++f) {
    s.frames.push_back({&s.weights[f], &s.disp[f], &s.observed[f]});
  }
  return s;
}

std::vector<std::vector<int>> Neighbours(const ShapeData& data) {
  // Every bundle's neighbours: the next two (enough for the test's costs).
  const int K = data.num_bundles;
  std::vector<std::vector<int>> nb(K);
  for (int k = 0; k < K; ++k) nb[k] = {(k + 1) % K, (k + 2) % K};
  return nb;
}

class TemporalCoherence : public ::testing::TestWithParam<int> {};

TEST_P(TemporalCoherence, ExactAnswersAndUnrelatedFramesAreKept) {
  testing::LgiTestActorOptions o;
  o.seed = GetParam();
  const ShapeData data = ComputeShapeData(testing::MakeLgiTestActor(o));
  const int N = data.num_shapes;
  std::mt19937 rng(GetParam());
  std::uniform_real_distribution<double> u(0.0, 1.0);
  // Unrelated frames (a random shape each at full weight), answered
  // exactly: nothing changes, noise-free or not.
  std::vector<Eigen::VectorXd> truth;
  for (int f = 0; f < 8; ++f) {
    Eigen::VectorXd w = Eigen::VectorXd::Zero(N);
    w[(f * 5 + GetParam()) % N] = 1.0;
    truth.push_back(w);
  }
  TemporalCoherenceOptions options;
  Sequence exact = Make(data, truth, truth, 0.0, GetParam());
  EXPECT_EQ(SmoothAnswersInTime(data, Neighbours(data), exact.numbers,
                                options, &exact.frames, nullptr),
            0);
  // The same with 0.05 mm noise and that noise level: the answers are not
  // exact, but the average of unrelated frames explains nothing.
  options.noise2 = 0.05 * 0.05;
  Sequence noisy = Make(data, truth, truth, 0.05, GetParam());
  std::vector<std::vector<char>> changed;
  SmoothAnswersInTime(data, Neighbours(data), noisy.numbers, options,
                      &noisy.frames, &changed);
  int64_t moved = 0, total = 0;
  for (const auto& row : changed) {
    for (char c : row) {
      moved += c;
      ++total;
    }
  }
  // Only bundles that no shape of the window moves may take the average.
  for (size_t f = 0; f < changed.size(); ++f) {
    for (int k = 0; k < data.num_bundles; ++k) {
      if (!changed[f][k]) continue;
      for (int g = std::max<int>(0, f - 2); g <= std::min<int>(7, f + 2); ++g) {
        for (int i = 0; i < N; ++i) {
          if (truth[g][i] == 0) continue;
          EXPECT_LT(data.SiteDisplacement(i, k).norm(), 0.5)
              << "frame " << f << " bundle " << k << " shape " << i;
        }
      }
    }
  }
  EXPECT_LT(moved, total);
}

TEST_P(TemporalCoherence, AlternatingAnswersOfASmoothTakeAreAveraged) {
  testing::LgiTestActorOptions o;
  o.seed = GetParam();
  const ShapeData data = ComputeShapeData(testing::MakeLgiTestActor(o));
  const int N = data.num_shapes;
  // A slow ramp of shape 0 answered alternately too high and too low (a
  // switching choice): the average is the ramp, closer to the truth.
  std::vector<Eigen::VectorXd> truth, answer;
  for (int f = 0; f < 12; ++f) {
    Eigen::VectorXd w = Eigen::VectorXd::Zero(N);
    w[0] = 0.3 + 0.02 * f;
    truth.push_back(w);
    w[0] += (f % 2 ? 0.05 : -0.05);
    answer.push_back(w);
  }
  TemporalCoherenceOptions options;
  options.noise2 = 0.0;
  options.tolerance = 0.0;
  Sequence s = Make(data, truth, answer, 0.0, GetParam());
  std::vector<std::vector<char>> changed;
  const int64_t count = SmoothAnswersInTime(data, Neighbours(data), s.numbers,
                                            options, &s.frames, &changed);
  EXPECT_GT(count, 0);
  for (int f = 2; f < 10; ++f) {
    for (int k = 0; k < data.num_bundles; ++k) {
      if (data.SiteDisplacement(0, k).norm() < 1e-6) continue;
      ASSERT_TRUE(changed[f][k]) << f << " " << k;
      ASSERT_EQ(s.weights[f][k].size(), 1u);
      EXPECT_EQ(s.weights[f][k][0].first, 0);
      // Triangular weights 1 2 3 2 1 over the alternating +-0.05: 0.0056
      // off the ramp at most, against 0.05 before.
      EXPECT_LT(std::abs(s.weights[f][k][0].second - truth[f][0]), 0.006)
          << f << " " << k;
    }
  }
  // Off: nothing changes.
  options.window = 1;
  Sequence off = Make(data, truth, answer, 0.0, GetParam());
  EXPECT_EQ(SmoothAnswersInTime(data, Neighbours(data), off.numbers, options,
                                &off.frames, nullptr),
            0);
}

// The lag-1 correlation tells a take from unrelated frames: independent
// random displacements give about 0, a smooth motion near 1, and noise on
// a smooth motion is taken out when its level is given.
TEST_P(TemporalCoherence, LagOneCorrelationTellsATakeFromUnrelatedFrames) {
  std::mt19937 rng(GetParam());
  std::normal_distribution<double> n(0.0, 1.0);
  const int F = 60, K = 40;
  std::vector<std::vector<Vec3>> independent(F, std::vector<Vec3>(K)), smooth = independent,
                                                                         noisy = independent;
  std::vector<Vec3> amplitude(K), phase(K);
  for (int k = 0; k < K; ++k) {
    amplitude[k] = 2.0 * Vec3(n(rng), n(rng), n(rng));
    phase[k] = Vec3(n(rng), n(rng), n(rng));
  }
  const double noise = 0.3;
  for (int f = 0; f < F; ++f) {
    for (int k = 0; k < K; ++k) {
      independent[f][k] = 2.0 * Vec3(n(rng), n(rng), n(rng));
      for (int c = 0; c < 3; ++c) {
        // A take at 30 frames/s: movements of about a second.
        smooth[f][k][c] = amplitude[k][c] * std::sin(2 * M_PI * f / 30.0 + phase[k][c]);
      }
      noisy[f][k] = smooth[f][k] + noise * Vec3(n(rng), n(rng), n(rng));
    }
  }
  std::vector<int> numbers(F);
  for (int f = 0; f < F; ++f) numbers[f] = f + 1;
  const std::vector<char> all(K, 1);
  const std::vector<const std::vector<char>*> observed(F, &all);
  auto rho = [&](const std::vector<std::vector<Vec3>>& d, double noise2) {
    std::vector<const std::vector<Vec3>*> disp;
    for (const auto& frame : d) disp.push_back(&frame);
    return LagOneCorrelation(numbers, disp, observed, noise2);
  };
  EXPECT_LT(std::abs(rho(independent, 0.0)), 0.2);
  EXPECT_GT(rho(smooth, 0.0), 0.9);
  const double with_noise = rho(noisy, noise * noise);
  EXPECT_GT(with_noise, 0.85);
  EXPECT_GT(with_noise, rho(noisy, 0.0));  // the noise taken out raises it
  EXPECT_GE(rho(smooth, 0.0), kTakeCorrelation);
  EXPECT_LT(rho(independent, 0.0), kTakeCorrelation);
  // Frames that are not consecutive are no step of a take.
  std::vector<int> gaps(F);
  for (int f = 0; f < F; ++f) gaps[f] = 2 * f;
  std::vector<const std::vector<Vec3>*> disp;
  for (const auto& frame : smooth) disp.push_back(&frame);
  EXPECT_EQ(LagOneCorrelation(gaps, disp, observed, 0.0), 0.0);
}

// Step 3c: a bundle whose answer switches between lgi's and the global one
// from frame to frame gets the frame's global answer plus the moving
// average of its detail (answer less global); bundles without a local
// answer in the window are left alone; a gap in the frame numbers breaks
// the window.
TEST(TemporalCoherenceDetail, SwitchingDetailIsAveragedAroundTheGlobalAnswer) {
  const int F = 9, K = 3;
  std::vector<std::vector<std::pair<int, double>>> global(F);
  std::vector<std::vector<std::vector<std::pair<int, double>>>> answers(
      F, std::vector<std::vector<std::pair<int, double>>>(K)),
      detail(F);
  std::vector<std::vector<char>> use_global(F, std::vector<char>(K, 1)), changed(F);
  const std::vector<char> observed(K, 1);
  std::vector<int> numbers;
  for (int f = 0; f < F; ++f) {
    global[f] = {{0, 0.1 * f}, {1, 0.5}};
    if (f % 2 == 0) {  // bundle 0 takes lgi's answer in even frames
      answers[f][0] = {{0, 0.1 * f + 0.2}, {2, 0.3}};
      use_global[f][0] = 0;
    }
    numbers.push_back(f < 7 ? f : f + 5);  // frames 7, 8 after a gap
  }
  std::vector<DetailFrame> frames(F);
  for (int f = 0; f < F; ++f) {
    frames[f] = {&global[f], &answers[f], &use_global[f], &observed, &detail[f], &changed[f]};
  }
  const int64_t count = SmoothDetailInTime(numbers, 5, &frames);
  // The detail of an even frame: +0.2 on shape 0, -0.5 on shape 1 (lgi's
  // answer holds none of it), +0.3 on shape 2.
  auto expect_detail = [&](int f, double share) {
    ASSERT_TRUE(changed[f][0]) << f;
    std::map<int, double> d(detail[f][0].begin(), detail[f][0].end());
    ASSERT_EQ(d.size(), 3u) << f;
    EXPECT_NEAR(d[0], share * 0.2, 1e-12) << f;
    EXPECT_NEAR(d[1], -share * 0.5, 1e-12) << f;
    EXPECT_NEAR(d[2], share * 0.3, 1e-12) << f;
  };
  // Frame 3 (odd, global): the detail of frames 2 and 4, weight 2 each of
  // 1 2 3 2 1 = 9. Frame 4 (even): its own 3/9, frames 2 and 6 1/9 each.
  expect_detail(3, 4.0 / 9);
  expect_detail(4, 5.0 / 9);
  // Frame 8 follows a gap: only frame 7 (odd: global) is in its window,
  // so it keeps 3 / (3 + 2) of its own detail.
  expect_detail(8, 3.0 / 5);
  // The bundles that never leave the global answer are left alone.
  for (int f = 0; f < F; ++f) {
    EXPECT_FALSE(changed[f][1]);
    EXPECT_TRUE(detail[f][2].empty());
  }
  EXPECT_EQ(count, F);  // bundle 0 in every frame
  // Off: nothing changes.
  EXPECT_EQ(SmoothDetailInTime(numbers, 1, &frames), 0);
  for (int f = 0; f < F; ++f) EXPECT_FALSE(changed[f][0]);
}

// The residuals of a take averaged per bundle over 5 frames: exact for a
// residual linear in time (a smooth motion), the variance of independent
// noise down to 19/81 inside the take (sum t^2 / (sum t)^2) and by less at
// its ends and beside a gap or an unobserved frame, where the window is
// cut.
TEST_P(TemporalCoherence, ResidualsOfATakeAverageTheNoiseAndKeepASmoothMotion) {
  std::mt19937 rng(GetParam());
  std::normal_distribution<double> n(0.0, 1.0);
  const int F = 400, K = 4;
  std::vector<int> numbers;
  std::vector<std::vector<char>> seen(F, std::vector<char>(K, 1));
  std::vector<std::vector<Vec3>> linear(F, std::vector<Vec3>(K)), noise = linear;
  for (int f = 0; f < F; ++f) {
    numbers.push_back(f < 200 ? f : f + 3);  // a gap after frame 199
    for (int k = 0; k < K; ++k) {
      linear[f][k] = Vec3(0.1 * f, -0.05 * f + k, 2.0);
      noise[f][k] = Vec3(n(rng), n(rng), n(rng));
    }
  }
  seen[50][2] = 0;  // bundle 2 unobserved in frame 50
  std::vector<const std::vector<char>*> observed;
  for (const auto& o : seen) observed.push_back(&o);
  std::vector<std::vector<Vec3>> averaged;
  std::vector<std::vector<double>> q;
  AverageInTake(numbers, observed, linear, 5, &averaged, &q);
  for (int f : {2, 100, 197, 202, 300}) {
    EXPECT_LT((averaged[f][0] - linear[f][0]).norm(), 1e-12) << f;
    EXPECT_NEAR(q[f][0], 19.0 / 81, 1e-12) << f;
  }
  // At the ends of the take and beside the gap: cut windows, more variance
  // kept (frame 0: weights 3 2 1, 14/36).
  EXPECT_NEAR(q[0][0], 14.0 / 36, 1e-12);
  EXPECT_NEAR(q[199][0], 14.0 / 36, 1e-12);
  EXPECT_NEAR(q[200][0], 14.0 / 36, 1e-12);
  EXPECT_GT(q[51][2], 19.0 / 81);  // frame 50 left out of bundle 2's window
  EXPECT_NEAR(q[51][1], 19.0 / 81, 1e-12);
  // The whole window's factor, as step 5 takes it for its floor.
  EXPECT_EQ(WholeWindowVarianceFactor(5), q[100][0]);
  EXPECT_NEAR(WholeWindowVarianceFactor(3), 6.0 / 16, 1e-15);  // weights 1 2 1
  EXPECT_EQ(WholeWindowVarianceFactor(1), 1.0);
  // Independent noise: the averaged variance as q says (inside the take).
  AverageInTake(numbers, observed, noise, 5, &averaged, &q);
  double sum2 = 0;
  int count = 0;
  for (int f = 10; f < 190; ++f) {
    sum2 += averaged[f][0].squaredNorm() / 3;
    ++count;
  }
  EXPECT_NEAR(sum2 / count, 19.0 / 81, 0.05);  // ~0.235; the mean of 180 correlated values
  // Off (window 1): the values themselves.
  AverageInTake(numbers, observed, noise, 1, &averaged, &q);
  EXPECT_EQ(averaged[7][3], noise[7][3]);
  EXPECT_EQ(q[7][3], 1.0);
}

// FrameSolve::Weights: a bundle's answer whichever way it is held.
TEST(TemporalCoherenceDetail, FrameWeightsAddTheShareOfTheGlobalAnswer) {
  FrameSolve fs;
  fs.bundles.resize(3);
  fs.global_weights = {{0, 0.5}, {2, 0.25}};
  fs.bundles[0].weights = {{1, 1.0}};
  fs.bundles[1].global_share = 1.0;
  fs.bundles[2].global_share = 0.4;
  fs.bundles[2].weights = {{1, 0.1}, {2, -0.1}, {3, 0.2}};
  using W = std::vector<std::pair<int, double>>;
  EXPECT_EQ(fs.Weights(0), (W{{1, 1.0}}));
  EXPECT_EQ(fs.Weights(1), fs.global_weights);
  const W mixed = fs.Weights(2);  // shape 2: 0.4 * 0.25 - 0.1 cancels
  ASSERT_EQ(mixed.size(), 3u);
  EXPECT_EQ(mixed[0].first, 0);
  EXPECT_NEAR(mixed[0].second, 0.2, 1e-15);
  EXPECT_EQ(mixed[1], (std::pair<int, double>{1, 0.1}));
  EXPECT_EQ(mixed[2], (std::pair<int, double>{3, 0.2}));
}

INSTANTIATE_TEST_SUITE_P(Seeds, TemporalCoherence, ::testing::Values(1, 2, 3));

}  // namespace
}  // namespace hmc
