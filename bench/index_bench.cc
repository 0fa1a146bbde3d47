// Index build on the default synthetic actor (SynthActorOptions defaults):
// unskinned shapes, natural-neighbour weights, point clouds, tetrahedra and
// grids. Counters: kept tetrahedra, index memory, peak resident memory of
// the process (maxrss). Results: docs/PERFORMANCE.md.
#include <benchmark/benchmark.h>

#include "bench/bench_util.h"
#include "blending/solve_index_cache.h"

namespace hmc {
namespace {

void BM_IndexBuild(benchmark::State& state) {
  const Actor& actor = DefaultActor();
  LgiBuildOptions options;
  int64_t kept = 0, memory = 0, points = 0;
  for (auto _ : state) {
    LgiModel model = BuildLgiModel(actor, options.index, options.nn);
    kept = memory = points = 0;
    for (const auto& b : model.index.bundles) {
      kept += b.stats().tets_kept;
      points += b.stats().points;
    }
    memory = model.index.MemoryBytes();
    benchmark::DoNotOptimize(model);
  }
  state.counters["bundles"] = static_cast<double>(actor.markers.size());
  state.counters["shapes"] = static_cast<double>(actor.shapes.size());
  state.counters["vertices"] = actor.NumVertices();
  state.counters["points"] = static_cast<double>(points);
  state.counters["tets_kept"] = static_cast<double>(kept);
  state.counters["index_MB"] = memory / 1048576.0;
  state.counters["peak_RSS_MB"] = PeakRssMb();
}
BENCHMARK(BM_IndexBuild)->Unit(benchmark::kSecond)->Iterations(1);

void BM_PointCloudsAndTetrahedra(benchmark::State& state) {
  const Actor& actor = DefaultActor();
  LgiBuildOptions options;
  const ShapeData data = ComputeShapeData(actor);
  const NaturalNeighbourWeights nn =
      ComputeNaturalNeighbourWeights(actor.neutral, data.sites, options.nn);
  const auto regions = RegionsOfInfluence(nn);
  for (auto _ : state) {
    ShapeIndex index = BuildShapeIndex(actor, data, regions, options.index);
    benchmark::DoNotOptimize(index);
  }
}
BENCHMARK(BM_PointCloudsAndTetrahedra)->Unit(benchmark::kSecond)->Iterations(1);

}  // namespace
}  // namespace hmc

BENCHMARK_MAIN();
