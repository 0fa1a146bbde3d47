#include "core/error_stats.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

namespace hmc {
namespace {

class ErrorStatsSeeded : public ::testing::TestWithParam<int> {};

// Random sets of 1..500 non-negative values, of varied scale.
std::vector<std::vector<double>> RandomSets(int seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> size(1, 500);
  std::exponential_distribution<double> value(0.7);
  std::vector<std::vector<double>> sets(20);
  for (auto& v : sets) {
    v.resize(size(rng));
    for (double& x : v) x = value(rng);
  }
  return sets;
}

TEST_P(ErrorStatsSeeded, StatsAgreeWithSorting) {
  for (std::vector<double> v : RandomSets(GetParam())) {
    std::vector<double> sorted = v;
    std::sort(sorted.begin(), sorted.end());
    double sum = 0, sum2 = 0;
    for (double x : sorted) {
      sum += x;
      sum2 += x * x;
    }
    const size_t n = sorted.size();
    // Nearest rank: smallest value with at least 95% at or below it.
    size_t rank = 1;
    while (static_cast<double>(rank) < 0.95 * n) ++rank;
    ErrorAccumulator sums;
    for (double x : v) sums.Add(x);
    EXPECT_EQ(sums.count, static_cast<int64_t>(n));
    EXPECT_NEAR(sums.Mean(), sum / n, 1e-12 * (1 + sum));
    EXPECT_NEAR(sums.Rms(), std::sqrt(sum2 / n), 1e-12 * (1 + sum2));
    EXPECT_EQ(sums.max, sorted.back());
    const ErrorStats s = ComputeErrorStats(&v);
    EXPECT_EQ(s.count, static_cast<int64_t>(n));
    EXPECT_NEAR(s.mean, sum / n, 1e-12 * (1 + sum));
    EXPECT_NEAR(s.rms, std::sqrt(sum2 / n), 1e-12 * (1 + sum2));
    EXPECT_EQ(s.max, sorted.back());
    EXPECT_EQ(s.p95, sorted[rank - 1]);
  }
  std::vector<double> empty;
  const ErrorStats none = ComputeErrorStats(&empty);
  EXPECT_EQ(none.count, 0);
  EXPECT_EQ(none.rms, 0.0);
  EXPECT_EQ(none.p95, 0.0);
  const ErrorAccumulator nothing;
  EXPECT_EQ(nothing.Mean(), 0.0);
  EXPECT_EQ(nothing.Rms(), 0.0);
}

// The definition: the smallest value with at least q of the set at or below
// it, counted on the sorted set, for any q.
TEST_P(ErrorStatsSeeded, PercentileIsTheSmallestValueCoveringTheShare) {
  std::mt19937 rng(GetParam() + 100);
  std::uniform_real_distribution<double> share(0.001, 1.0);
  for (std::vector<double> v : RandomSets(GetParam())) {
    std::vector<double> sorted = v;
    std::sort(sorted.begin(), sorted.end());
    const double q = share(rng);
    const double p = NearestRankPercentile(&v, q);
    const auto at_or_below = [&](double x) {
      return static_cast<double>(std::upper_bound(sorted.begin(), sorted.end(), x) -
                                 sorted.begin());
    };
    EXPECT_GE(at_or_below(p), q * sorted.size());
    const auto first = std::lower_bound(sorted.begin(), sorted.end(), p);
    if (first != sorted.begin()) {
      EXPECT_LT(at_or_below(*(first - 1)), q * sorted.size());
    }
    std::vector<double> again = sorted;
    EXPECT_EQ(NearestRankPercentile(&again, 1.0), sorted.back());
  }
}

TEST_P(ErrorStatsSeeded, UpperMedianAndMeanAgreeWithSorting) {
  for (std::vector<double> v : RandomSets(GetParam())) {
    std::vector<double> sorted = v;
    std::sort(sorted.begin(), sorted.end());
    double sum = 0;
    for (double x : v) sum += x;
    EXPECT_EQ(MeanOf(v), sum / v.size());
    EXPECT_EQ(UpperMedian(&v), sorted[sorted.size() / 2]);
    // At least half the set at or below it, and at least half at or above.
    const double m = sorted[sorted.size() / 2];
    const auto below = std::upper_bound(sorted.begin(), sorted.end(), m) - sorted.begin();
    const auto above = sorted.end() - std::lower_bound(sorted.begin(), sorted.end(), m);
    EXPECT_GE(2 * below, static_cast<long>(sorted.size()));
    EXPECT_GE(2 * above, static_cast<long>(sorted.size()));
  }
  EXPECT_EQ(MeanOf({}), 0.0);
}

INSTANTIATE_TEST_SUITE_P(Seeds, ErrorStatsSeeded, ::testing::Values(1, 2, 3, 7));

}  // namespace
}  // namespace hmc
