#include "blending/temporal_coherence.h"

#include <random>

#include <gtest/gtest.h>

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

INSTANTIATE_TEST_SUITE_P(Seeds, TemporalCoherence, ::testing::Values(1, 2, 3));

}  // namespace
}  // namespace hmc
