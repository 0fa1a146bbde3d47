// Summaries of sets of errors, shared by every place that reports them: the
// reconstruction metrics of `hmc eval` and `hmc experiment`
// (core/mesh_metrics.h, eval/eval_metrics.h), the head and jaw pose errors
// against ground truth (stabilization/accuracy.h) and the solve's medians
// (blending/). One definition of each statistic, so the same numbers mean
// the same everywhere.
//
// Conventions (kept as each caller had them, so outputs are unchanged):
// - the mean and RMS of an empty set are 0;
// - percentiles are nearest rank: the smallest value with at least a share q
//   of the set at or below it (no interpolation);
// - the median is the upper one, the element at index n / 2 of the sorted
//   set (for even n the larger of the two middle values), which is what the
//   solve's noise bound and marker spacing have always used. (pipeline's
//   report uses nearest rank for its median, the lower one for even n.)
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

namespace hmc {

// Count, sum, sum of squares and maximum of non-negative values, added one
// at a time (in a fixed order, so the sums are reproducible).
struct ErrorAccumulator {
  int64_t count = 0;
  double sum = 0.0;
  double sum2 = 0.0;
  double max = 0.0;  // 0 for an empty set

  void Add(double x) {
    ++count;
    sum += x;
    sum2 += x * x;
    max = std::max(max, x);
  }
  double Mean() const { return count > 0 ? sum / static_cast<double>(count) : 0.0; }
  double Rms() const {
    return count > 0 ? std::sqrt(sum2 / static_cast<double>(count)) : 0.0;
  }
};

// Mean of `values` (0 for an empty set).
double MeanOf(const std::vector<double>& values);

// Nearest-rank percentile, q in (0, 1]: the smallest value with at least
// q of the set at or below it. `values` non-empty; reordered (partial sort).
double NearestRankPercentile(std::vector<double>* values, double q);

// The upper median: the element at index n / 2 of the sorted set.
// `values` non-empty; reordered (partial sort).
double UpperMedian(std::vector<double>* values);

// Mean, RMS, 95th percentile (nearest rank) and maximum of a set of
// non-negative values (mm); all zero for an empty set.
struct ErrorStats {
  int64_t count = 0;
  double mean = 0.0;
  double rms = 0.0;
  double p95 = 0.0;
  double max = 0.0;
};

// Statistics of `values`; the vector is reordered (partial sort).
ErrorStats ComputeErrorStats(std::vector<double>* values);

}  // namespace hmc
