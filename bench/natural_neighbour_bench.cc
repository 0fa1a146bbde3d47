// Natural-neighbour weights of the default synthetic actor (51,200 vertices,
// its painted markers as sites), both domains. Run:
//   build/bin/hmc_natural_neighbour_bench
// Results and machine: docs/PERFORMANCE.md, "Natural-neighbour weights".
#include <algorithm>
#include <cmath>

#include <benchmark/benchmark.h>
#include <Eigen/SparseCore>

#include "bench/bench_util.h"
#include "blending/natural_neighbour.h"

namespace hmc {
namespace {

// Continuity measure: the largest L1 change of the weight rows along one
// mesh edge, for edges across cell borders and inside cells.
void CountEdgeJumps(const Actor& actor, const NaturalNeighbourWeights& nn,
                    benchmark::State& state) {
  const MatX3i& F = actor.neutral.F;
  double across = 0.0, inside = 0.0;
  for (int f = 0; f < F.rows(); ++f) {
    for (int i = 0; i < 3; ++i) {
      const int a = F(f, i), b = F(f, (i + 1) % 3);
      const Eigen::SparseVector<double> diff = nn.weights.row(a) - nn.weights.row(b);
      double jump = 0.0;
      for (Eigen::SparseVector<double>::InnerIterator it(diff); it; ++it) {
        jump += std::abs(it.value());
      }
      double& slot = nn.cell[a] != nn.cell[b] ? across : inside;
      slot = std::max(slot, jump);
    }
  }
  state.counters["jump_across"] = across;
  state.counters["jump_inside"] = inside;
  state.counters["nnz_per_vertex"] =
      static_cast<double>(nn.weights.nonZeros()) / nn.weights.rows();
}

std::vector<SurfacePoint> Sites(const Actor& actor) {
  std::vector<SurfacePoint> sites;
  for (const Marker& marker : actor.markers) sites.push_back(marker.point);
  return sites;
}

// Times the weights with `options`; counters: continuity and the sizes.
void WeightsBench(benchmark::State& state, const NaturalNeighbourOptions& options) {
  const Actor& actor = DefaultActor();
  NaturalNeighbourWeights nn;
  for (auto _ : state) {
    nn = ComputeNaturalNeighbourWeights(actor.neutral, Sites(actor), options);
    benchmark::DoNotOptimize(nn);
  }
  CountEdgeJumps(actor, nn, state);
  state.counters["vertices"] = actor.NumVertices();
  state.counters["sites"] = static_cast<double>(actor.markers.size());
}

void BM_NaturalNeighbourUv(benchmark::State& state) {
  NaturalNeighbourOptions options;
  options.domain = "uv";
  options.uv_resolution = static_cast<int>(state.range(0));
  WeightsBench(state, options);
}
BENCHMARK(BM_NaturalNeighbourUv)
    ->Arg(512)->Arg(1024)->Arg(2048)
    ->Unit(benchmark::kMillisecond)->Iterations(1)->UseRealTime();

// Raster error of the UV weights: L1 difference of each weight row to the
// weights at 2048 px (max and mean over vertices), as counters.
void BM_NaturalNeighbourUvRasterError(benchmark::State& state) {
  const Actor& actor = DefaultActor();
  NaturalNeighbourOptions options;
  options.domain = "uv";
  options.uv_resolution = 2048;
  static const NaturalNeighbourWeights reference =
      ComputeNaturalNeighbourWeights(actor.neutral, Sites(actor), options);
  options.uv_resolution = static_cast<int>(state.range(0));
  NaturalNeighbourWeights nn;
  for (auto _ : state) {
    nn = ComputeNaturalNeighbourWeights(actor.neutral, Sites(actor), options);
    benchmark::DoNotOptimize(nn);
  }
  double max_error = 0.0, mean_error = 0.0;
  for (int v = 0; v < actor.NumVertices(); ++v) {
    const Eigen::SparseVector<double> diff =
        nn.weights.row(v) - reference.weights.row(v);
    double error = 0.0;
    for (Eigen::SparseVector<double>::InnerIterator it(diff); it; ++it) {
      error += std::abs(it.value());
    }
    max_error = std::max(max_error, error);
    mean_error += error / actor.NumVertices();
  }
  state.counters["l1_vs_2048_max"] = max_error;
  state.counters["l1_vs_2048_mean"] = mean_error;
}
BENCHMARK(BM_NaturalNeighbourUvRasterError)
    ->Arg(256)->Arg(512)->Arg(1024)
    ->Unit(benchmark::kMillisecond)->Iterations(1)->UseRealTime();

void BM_NaturalNeighbourGeodesic(benchmark::State& state) {
  NaturalNeighbourOptions options;
  options.domain = "geodesic";
  WeightsBench(state, options);
}
BENCHMARK(BM_NaturalNeighbourGeodesic)
    ->Unit(benchmark::kMillisecond)->Iterations(1)->UseRealTime();

}  // namespace
}  // namespace hmc

BENCHMARK_MAIN();
