// Per-frame solve on the default synthetic actor: index query, choice among
// candidates and blend (+ jaw skinning) of one frame. Frames: mixtures of two
// dataset shapes (unskinned, 50/50) under the mean of their jaw poses.
// Args: min_tet_quality x 1000, max_edge_mm (0 = no bound), so the cost of
// tetrahedron pruning can be read off: counters give the kept tetrahedra,
// candidates per bundle and the verification error (every dataset shape
// solved from its own bundles). Report the median of the repetitions.
// Results: docs/PERFORMANCE.md.
#include <map>
#include <random>

#include <benchmark/benchmark.h>

#include "blending/lgi_solver.h"
#include "blending/solve_index_cache.h"
#include "synth/synth_actor.h"

namespace hmc {
namespace {

struct Base {
  Base() : actor(SynthesizeActor(SynthActorOptions())) {
    data = ComputeShapeData(actor);
    nn = ComputeNaturalNeighbourWeights(actor.neutral, data.sites,
                                        NaturalNeighbourOptions());
    regions = RegionsOfInfluence(nn);
    std::mt19937 rng(7);
    const int N = data.num_shapes, V = actor.NumVertices();
    for (int f = 0; f < 32; ++f) {
      const int a = rng() % N, b = rng() % N;
      MatX3d x = actor.neutral.V;
      for (int v = 0; v < V; ++v) {
        const float* d = data.VertexDisplacements(v);
        for (int i = 0; i < 3; ++i) x(v, i) += 0.5 * (d[a * 3 + i] + d[b * 3 + i]);
      }
      JawPose pose;
      pose.open_deg = 0.5 * (actor.shapes[a].jaw.open_deg +
                             actor.shapes[b].jaw.open_deg);
      if (actor.jaw_rig) x = Skin(*actor.jaw_rig, pose, x);
      frames.push_back(Bundles(x, f + 1));
      jaw.push_back(pose);
    }
  }
  BundleFrame Bundles(const MatX3d& x, int frame) const {
    BundleFrame b;
    b.frame = frame;
    for (int k = 0; k < data.num_bundles; ++k) {
      b.bundles[data.bundle_names[k]] =
          EvaluateSurfacePoint(data.sites[k], actor.neutral.F, x);
    }
    return b;
  }
  Actor actor;
  ShapeData data;
  NaturalNeighbourWeights nn;
  std::vector<std::vector<int>> regions;
  std::vector<BundleFrame> frames;
  std::vector<JawPose> jaw;
};

Base& GetBase() {
  static Base base;
  return base;
}

struct Variant {
  IndexOptions options;
  ShapeIndex index;
  std::unique_ptr<LgiSolver> solver;
  double verification_error = 0.0;
  int64_t tets = 0;
};

Variant& GetVariant(int quality_milli, int max_edge_mm) {
  static std::map<std::pair<int, int>, std::unique_ptr<Variant>> variants;
  auto& slot = variants[{quality_milli, max_edge_mm}];
  if (slot) return *slot;
  Base& base = GetBase();
  slot = std::make_unique<Variant>();
  Variant& v = *slot;
  v.options.min_tet_quality = quality_milli / 1000.0;
  v.options.max_edge_mm = max_edge_mm;
  v.index = BuildShapeIndex(base.actor, base.data, base.regions, v.options);
  for (const auto& b : v.index.bundles) v.tets += b.stats().tets_kept;
  v.solver = std::make_unique<LgiSolver>(base.actor.neutral, base.data,
                                         v.index, base.nn, v.options,
                                         SolveOptions());
  for (int n = 0; n < base.data.num_shapes; ++n) {
    const MatX3d truth = base.actor.ShapePositions(n);
    FrameSolve f = v.solver->SolveFrame(base.Bundles(truth, n + 1),
                                        base.actor.shapes[n].jaw, nullptr);
    const MatX3d x = v.solver->Blend(&f);
    const double err = (x - truth).rowwise().norm().maxCoeff();
    v.verification_error = std::max(v.verification_error, err);
  }
  return v;
}

void BM_SolveFrame(benchmark::State& state) {
  Base& base = GetBase();
  Variant& v = GetVariant(static_cast<int>(state.range(0)),
                          static_cast<int>(state.range(1)));
  size_t f = 0;
  FrameSolve previous;
  double candidates = 0, projected = 0, bundles = 0;
  for (auto _ : state) {
    FrameSolve frame = v.solver->SolveFrame(
        base.frames[f], base.jaw[f], previous.ok ? &previous : nullptr);
    MatX3d mesh = v.solver->Blend(&frame);
    benchmark::DoNotOptimize(mesh.data());
    for (const auto& b : frame.bundles) {
      candidates += b.num_candidates;
      projected += b.status == BundleSolve::Status::kProjected;
      ++bundles;
    }
    previous = std::move(frame);
    f = (f + 1) % base.frames.size();
  }
  state.counters["tets_kept"] = static_cast<double>(v.tets);
  state.counters["candidates_per_bundle"] = candidates / bundles;
  state.counters["projected_fraction"] = projected / bundles;
  state.counters["verification_max_mm"] = v.verification_error;
}
BENCHMARK(BM_SolveFrame)
    ->Unit(benchmark::kMillisecond)
    ->Args({1, 0})
    ->Args({100, 8})
    ->Args({200, 6})
    ->Repetitions(3)
    ->ReportAggregatesOnly(true);

void BM_Blend(benchmark::State& state) {
  Base& base = GetBase();
  Variant& v = GetVariant(100, 8);
  FrameSolve frame = v.solver->SolveFrame(base.frames[0], base.jaw[0], nullptr);
  for (auto _ : state) {
    MatX3d mesh = v.solver->Blend(&frame);
    benchmark::DoNotOptimize(mesh.data());
  }
}
BENCHMARK(BM_Blend)->Unit(benchmark::kMillisecond)->Repetitions(3)
    ->ReportAggregatesOnly(true);

}  // namespace
}  // namespace hmc

BENCHMARK_MAIN();
