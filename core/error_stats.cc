#include "core/error_stats.h"

#include "core/error.h"

namespace hmc {

double MeanOf(const std::vector<double>& values) {
  double sum = 0;
  for (double x : values) sum += x;
  return values.empty() ? 0.0 : sum / values.size();
}

double NearestRankPercentile(std::vector<double>* values, double q) {
  HMC_CHECK(!values->empty() && q > 0 && q <= 1);
  const size_t n = values->size();
  const size_t rank = static_cast<size_t>(std::ceil(q * n));
  const size_t index = std::max<size_t>(rank, 1) - 1;
  std::nth_element(values->begin(), values->begin() + index, values->end());
  return (*values)[index];
}

double UpperMedian(std::vector<double>* values) {
  HMC_CHECK(!values->empty());
  const size_t mid = values->size() / 2;
  std::nth_element(values->begin(), values->begin() + mid, values->end());
  return (*values)[mid];
}

ErrorStats ComputeErrorStats(std::vector<double>* values) {
  ErrorStats s;
  if (values->empty()) return s;
  ErrorAccumulator sums;
  for (double x : *values) sums.Add(x);
  s.count = sums.count;
  s.mean = sums.Mean();
  s.rms = sums.Rms();
  s.max = sums.max;
  s.p95 = NearestRankPercentile(values, 0.95);
  return s;
}

}  // namespace hmc
