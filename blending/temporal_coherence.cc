#include "blending/temporal_coherence.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>

#include "core/error.h"
#include "core/parallel.h"

namespace hmc {
namespace {

// sum_{j in {k} + nbhd(k), observed} |d_j - B_j w|^2 for dense weights w
// given by their non-zero entries; *count: the bundles summed.
double NeighbourhoodCost(const ShapeData& data, const std::vector<int>& nbhd,
                         int k, const TemporalFrame& frame,
                         const std::vector<std::pair<int, double>>& w,
                         int* count) {
  double cost = 0.0;
  *count = 0;
  auto add = [&](int j) {
    if (!(*frame.observed)[j]) return;
    Vec3 x = Vec3::Zero();
    for (const auto& [n, wn] : w) x += wn * data.SiteDisplacement(n, j);
    cost += ((*frame.disp)[j] - x).squaredNorm();
    ++*count;
  };
  add(k);
  for (int j : nbhd) add(j);
  return cost;
}

// Visits frame f with weight h + 1, then each frame g of the centred
// window of half-width h, outwards, with the triangular weight
// h + 1 - |g - f|, while g is consecutive with f in frame numbers and
// observed(g): a gap or an unobserved frame ends that side of the window.
template <typename Observed, typename Visit>
void ForEachInWindow(const std::vector<int>& frame_numbers, int f, int h,
                     const Observed& observed, const Visit& visit) {
  const int F = static_cast<int>(frame_numbers.size());
  visit(f, h + 1.0);
  for (int dir : {-1, 1}) {
    for (int s = 1; s <= h; ++s) {
      const int g = f + dir * s;
      if (g < 0 || g >= F) break;
      if (std::abs(frame_numbers[g] - frame_numbers[f]) != s) break;
      if (!observed(g)) break;
      visit(g, h + 1.0 - s);
    }
  }
}

}  // namespace

int64_t SmoothAnswersInTime(const ShapeData& data,
                            const std::vector<std::vector<int>>& neighbours,
                            const std::vector<int>& frame_numbers,
                            const TemporalCoherenceOptions& options,
                            std::vector<TemporalFrame>* frames,
                            std::vector<std::vector<char>>* changed) {
  const int F = static_cast<int>(frames->size());
  const int K = data.num_bundles, N = data.num_shapes;
  HMC_CHECK(static_cast<int>(frame_numbers.size()) == F);
  HMC_CHECK(static_cast<int>(neighbours.size()) == K);
  if (changed) changed->assign(F, std::vector<char>(K, 0));
  if (options.window <= 1 || F < 2) return 0;
  const int h = options.window / 2;
  // The answers as they were (the average reads these, not its own output).
  std::vector<std::vector<std::vector<std::pair<int, double>>>> original(F);
  for (int f = 0; f < F; ++f) original[f] = *(*frames)[f].weights;
  std::vector<int64_t> taken(K, 0);
  ParallelFor(0, K, [&](int64_t k64) {
    const int k = static_cast<int>(k64);
    std::vector<double> dense(N, 0.0);
    std::vector<int> touched;
    for (int f = 0; f < F; ++f) {
      const TemporalFrame& frame = (*frames)[f];
      if (!(*frame.observed)[k]) continue;
      const std::vector<std::pair<int, double>>& own = original[f][k];
      int m = 0;
      const double cost = NeighbourhoodCost(data, neighbours[k], k, frame, own, &m);
      const double tie = m * options.tie_mm2;
      if (cost <= tie) continue;  // exact: kept
      // The triangular average over the window's frames that are
      // consecutive with f and observe the bundle.
      double total = 0.0;
      touched.clear();
      auto add = [&](int g, double t) {
        for (const auto& [n, w] : original[g][k]) {
          if (dense[n] == 0.0) touched.push_back(n);
          dense[n] += t * w;
          if (dense[n] == 0.0) dense[n] = 1e-300;  // keep it listed
        }
        total += t;
      };
      ForEachInWindow(frame_numbers, f, h,
                      [&](int g) { return (*(*frames)[g].observed)[k] != 0; }, add);
      std::sort(touched.begin(), touched.end());
      std::vector<std::pair<int, double>> average;
      average.reserve(touched.size());
      for (int n : touched) {
        const double w = dense[n] / total;
        if (std::abs(w) > 1e-200) average.emplace_back(n, w);
        dense[n] = 0.0;
      }
      if (total == h + 1.0) continue;  // no other frame in the window
      const double smoothed =
          NeighbourhoodCost(data, neighbours[k], k, frame, average, &m);
      if (smoothed <= cost + options.tolerance * 3.0 * options.noise2 * m + tie) {
        (*frame.weights)[k] = std::move(average);
        ++taken[k];
        if (changed) (*changed)[f][k] = 1;
      }
    }
  });
  int64_t sum = 0;
  for (int64_t t : taken) sum += t;
  return sum;
}

double LagOneCorrelation(const std::vector<int>& frame_numbers,
                         const std::vector<const std::vector<Vec3>*>& disp,
                         const std::vector<const std::vector<char>*>& observed,
                         double noise2) {
  const int F = static_cast<int>(frame_numbers.size());
  HMC_CHECK(static_cast<int>(disp.size()) == F && static_cast<int>(observed.size()) == F);
  if (F < 3) return 0.0;
  const int K = static_cast<int>(disp[0]->size());
  // Per marker: mean and variance over the frames that observe it.
  double var_sum = 0.0;
  int64_t var_count = 0;
  for (int k = 0; k < K; ++k) {
    Vec3 mean = Vec3::Zero();
    int n = 0;
    for (int f = 0; f < F; ++f) {
      if ((*observed[f])[k]) mean += (*disp[f])[k], ++n;
    }
    if (n < 2) continue;
    mean /= n;
    double ss = 0.0;
    for (int f = 0; f < F; ++f) {
      if ((*observed[f])[k]) ss += ((*disp[f])[k] - mean).squaredNorm();
    }
    var_sum += ss / (n - 1);
    ++var_count;
  }
  double step_sum = 0.0;
  int64_t step_count = 0;
  for (int f = 0; f + 1 < F; ++f) {
    if (frame_numbers[f + 1] - frame_numbers[f] != 1) continue;
    for (int k = 0; k < K; ++k) {
      if (!(*observed[f])[k] || !(*observed[f + 1])[k]) continue;
      step_sum += ((*disp[f + 1])[k] - (*disp[f])[k]).squaredNorm();
      ++step_count;
    }
  }
  if (var_count == 0 || step_count == 0) return 0.0;
  const double variance = var_sum / var_count - 3.0 * noise2;
  const double step = step_sum / step_count - 6.0 * noise2;
  if (!(variance > 0)) return 0.0;  // nothing moves beyond the noise
  // Clamped: with the noise taken out, an estimate may pass 1 (a noise
  // level estimated high) or -1.
  return std::clamp(1.0 - step / (2.0 * variance), -1.0, 1.0);
}

int64_t SmoothDetailInTime(const std::vector<int>& frame_numbers, int window,
                           std::vector<DetailFrame>* frames) {
  const int F = static_cast<int>(frames->size());
  HMC_CHECK(static_cast<int>(frame_numbers.size()) == F);
  for (DetailFrame& frame : *frames) {
    frame.detail->assign(frame.answers->size(), {});
    frame.changed->assign(frame.answers->size(), 0);
  }
  if (window <= 1 || F < 2) return 0;
  const int K = static_cast<int>((*frames)[0].answers->size());
  const int h = window / 2;
  std::vector<int64_t> count(K, 0);
  ParallelFor(0, K, [&](int64_t k64) {
    const int k = static_cast<int>(k64);
    std::map<int, double> sum;  // shape -> weighted detail
    for (int f = 0; f < F; ++f) {
      const DetailFrame& frame = (*frames)[f];
      if (!(*frame.observed)[k]) continue;
      sum.clear();
      double total = 0.0;
      bool any_detail = false;
      // The detail of bundle k in frame g: its answer less the global one.
      auto add = [&](int g, double t) {
        total += t;
        const DetailFrame& other = (*frames)[g];
        if ((*other.use_global)[k]) return;
        any_detail = true;
        for (const auto& [n, w] : (*other.answers)[k]) sum[n] += t * w;
        for (const auto& [n, w] : *other.global) sum[n] -= t * w;
      };
      ForEachInWindow(frame_numbers, f, h,
                      [&](int g) { return (*(*frames)[g].observed)[k] != 0; }, add);
      if (!any_detail || total == h + 1.0) continue;  // no detail, or no other frame
      std::vector<std::pair<int, double>>& detail = (*frame.detail)[k];
      detail.reserve(sum.size());
      for (const auto& [n, w] : sum) {
        if (w != 0.0) detail.emplace_back(n, w / total);
      }
      (*frame.changed)[k] = 1;
      ++count[k];
    }
  });
  int64_t out = 0;
  for (int64_t c : count) out += c;
  return out;
}

void AverageInTake(const std::vector<int>& frame_numbers,
                   const std::vector<const std::vector<char>*>& observed,
                   const std::vector<std::vector<Vec3>>& values, int window,
                   std::vector<std::vector<Vec3>>* averaged,
                   std::vector<std::vector<double>>* variance_factor) {
  const int F = static_cast<int>(values.size());
  HMC_CHECK(static_cast<int>(frame_numbers.size()) == F &&
            static_cast<int>(observed.size()) == F);
  const int h = std::max(window, 1) / 2;
  averaged->assign(F, {});
  variance_factor->assign(F, {});
  ParallelFor(0, F, [&](int64_t f64) {
    const int f = static_cast<int>(f64);
    const int K = static_cast<int>(values[f].size());
    (*averaged)[f].assign(K, Vec3::Zero());
    (*variance_factor)[f].assign(K, 1.0);
    for (int k = 0; k < K; ++k) {
      if (!(*observed[f])[k]) continue;
      Vec3 sum = Vec3::Zero();
      double total = 0.0, squares = 0.0;
      ForEachInWindow(
          frame_numbers, f, h, [&](int g) { return (*observed[g])[k] != 0; },
          [&](int g, double t) {
            sum += t * values[g][k];
            total += t;
            squares += t * t;
          });
      (*averaged)[f][k] = sum / total;
      (*variance_factor)[f][k] = squares / (total * total);
    }
  });
}

double WholeWindowVarianceFactor(int window) {
  const int h = std::max(window, 1) / 2;
  std::vector<int> numbers(2 * h + 1);  // consecutive frames
  std::iota(numbers.begin(), numbers.end(), 0);
  double total = 0.0, squares = 0.0;
  ForEachInWindow(
      numbers, h, h, [](int) { return true; },
      [&](int, double t) {
        total += t;
        squares += t * t;
      });
  return squares / (total * total);
}

}  // namespace hmc
