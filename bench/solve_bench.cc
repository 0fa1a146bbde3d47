// Per-frame solve on the default synthetic actor: index query, choice among
// candidates and blend (+ jaw skinning) of one frame of held-out random
// combinations. Args: min_tet_quality x 1000, max_edge_mm (0 = no bound),
// grid_max_cells, grid_entries_per_element, so
// the cost and the benefit of tetrahedron pruning can be read off together:
// counters give the kept tetrahedra, candidates per bundle, the
// verification error (every dataset shape solved from its own bundles) and
// the mean vertex error of held-out combinations and of a performance.
// Report the median of the repetitions. Results: docs/PERFORMANCE.md.
#include <map>
#include <tuple>

#include <benchmark/benchmark.h>

#include "bench/bench_util.h"
#include "blending/lgi_solver.h"
#include "blending/robust_solver.h"
#include "blending/solve_index_cache.h"
#include "synth/synth_actor.h"
#include "synth/truth_frames.h"

namespace hmc {
namespace {

struct Base {
  Base() : model(synth), actor(SynthesizeActorFromModel(model, synth)) {
    data = ComputeShapeData(actor);
    nn = ComputeNaturalNeighbourWeights(actor.neutral, data.sites,
                                        NaturalNeighbourOptions());
    regions = RegionsOfInfluence(nn);
    const std::vector<DatasetEntry> plan = PlanDataset(model, synth);
    // 24 combinations (seed 11) or a 48-frame performance (seed 12).
    const auto material = [&](const char* kind, double noise_mm) {
      TruthFramesOptions o;
      o.kind = kind;
      const bool combo = o.kind == "combos";
      o.frames = combo ? 24 : 48;
      o.seed = combo ? 11 : 12;
      o.noise_mm = noise_mm;
      return MakeTruthFrames(model, actor.markers, plan, o);
    };
    combos = material("combos", 0.0);
    performance = material("performance", 0.0);
    noisy_combos = material("combos", 0.5);
    noisy_performance = material("performance", 0.5);
  }
  // The frames of BM_RobustSequence / BM_BoundedSequence: 0 combinations,
  // 1 the same with 0.5 mm noise, 2 the performance (a take: the robust
  // default's temporal steps run), 3 the same with 0.5 mm noise.
  const TruthFrames& Material(int64_t m) const {
    const TruthFrames* all[] = {&combos, &noisy_combos, &performance,
                                &noisy_performance};
    return *all[m];
  }
  SynthActorOptions synth;
  FaceModel model;
  Actor actor;
  ShapeData data;
  NaturalNeighbourWeights nn;
  std::vector<std::vector<int>> regions;
  TruthFrames combos, performance;
  TruthFrames noisy_combos;  // the combinations with 0.5 mm marker noise
  TruthFrames noisy_performance;  // the performance with 0.5 mm noise
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
  double combos_mean = 0.0, performance_mean = 0.0;  // mean vertex error (mm)
  int64_t tets = 0;
};

// Mean over frames and vertices of |solve - truth| (mm), the sequence solved
// in order (so the temporal preference sees the previous frame).
double MeanError(const LgiSolver& solver, const TruthFrames& t) {
  const std::vector<JawPose> jaw = JawPoses(t.jaw);
  const SolveResult r = solver.SolveSequence(t.bundles, jaw);
  double sum = 0;
  for (size_t f = 0; f < t.positions.size(); ++f) {
    sum += (r.meshes[f] - t.positions[f]).rowwise().norm().mean();
  }
  return sum / t.positions.size();
}

Variant& GetVariant(int quality_milli, int max_edge_mm, int grid_max_cells,
                    int entries_per_element) {
  static std::map<std::tuple<int, int, int, int>, std::unique_ptr<Variant>>
      variants;
  auto& slot = variants[{quality_milli, max_edge_mm, grid_max_cells,
                         entries_per_element}];
  if (slot) return *slot;
  Base& base = GetBase();
  slot = std::make_unique<Variant>();
  Variant& v = *slot;
  v.options.min_tet_quality = quality_milli / 1000.0;
  v.options.max_edge_mm = max_edge_mm;
  v.options.grid_max_cells = grid_max_cells;
  v.options.grid_entries_per_element = entries_per_element;
  v.index = BuildShapeIndex(base.actor, base.data, base.regions, v.options);
  for (const auto& b : v.index.bundles) v.tets += b.stats().tets_kept;
  v.solver = std::make_unique<LgiSolver>(base.actor.neutral, base.data,
                                         v.index, base.nn, v.options,
                                         SolveOptions());
  for (int n = 0; n < base.data.num_shapes; ++n) {
    const MatX3d truth = base.actor.ShapePositions(n);
    FrameSolve f = v.solver->SolveFrame(BundlesOnMesh(base.data, base.actor.neutral.F, truth, n + 1),
                                        base.actor.shapes[n].jaw, nullptr);
    const MatX3d x = v.solver->Blend(&f);
    const double err = (x - truth).rowwise().norm().maxCoeff();
    v.verification_error = std::max(v.verification_error, err);
  }
  v.combos_mean = MeanError(*v.solver, base.combos);
  v.performance_mean = MeanError(*v.solver, base.performance);
  return v;
}

// One frame of held-out random combinations (synth/truth_frames.h, kind
// combos): query, choice and blend.
void BM_SolveFrame(benchmark::State& state) {
  Base& base = GetBase();
  Variant& v = GetVariant(static_cast<int>(state.range(0)),
                          static_cast<int>(state.range(1)),
                          static_cast<int>(state.range(2)),
                          static_cast<int>(state.range(3)));
  const TruthFrames& t = base.combos;
  size_t f = 0;
  double candidates = 0, projected = 0, bundles = 0;
  for (auto _ : state) {
    FrameSolve frame =
        v.solver->SolveFrame(t.bundles[f], t.jaw[f].pose, nullptr);
    MatX3d mesh = v.solver->Blend(&frame);
    benchmark::DoNotOptimize(mesh.data());
    for (const auto& b : frame.bundles) {
      candidates += b.num_candidates;
      projected += b.status == BundleSolve::Status::kProjected;
      ++bundles;
    }
    f = (f + 1) % t.bundles.size();
  }
  state.counters["tets_kept"] = static_cast<double>(v.tets);
  state.counters["index_mb"] = v.index.MemoryBytes() / 1e6;
  state.counters["candidates_per_bundle"] = candidates / bundles;
  state.counters["projected_fraction"] = projected / bundles;
  state.counters["verification_max_mm"] = v.verification_error;
  state.counters["combos_mean_mm"] = v.combos_mean;
  state.counters["performance_mean_mm"] = v.performance_mean;
}
BENCHMARK(BM_SolveFrame)
    ->Unit(benchmark::kMillisecond)
    ->MeasureProcessCPUTime()  // CPU column: all threads
    ->UseRealTime()
    ->Args({1, 0, 24, 8})
    ->Args({100, 8, 24, 8})
    ->Args({100, 8, 64, 32})
    ->Args({200, 6, 24, 8})
    ->Args({200, 6, 64, 32})
    ->Repetitions(3)
    ->ReportAggregatesOnly(true);

// Solves the state's material as one sequence per iteration (solve(frames,
// jaw) -> SolveResult) and sets s_per_frame.
template <typename Solve>
void SolveMaterial(benchmark::State& state, const Solve& solve) {
  const TruthFrames& t = GetBase().Material(state.range(0));
  const std::vector<JawPose> jaw = JawPoses(t.jaw);
  for (auto _ : state) {
    SolveResult r = solve(t.bundles, jaw);
    benchmark::DoNotOptimize(r.meshes.data());
  }
  state.counters["s_per_frame"] = benchmark::Counter(
      static_cast<double>(state.iterations() * t.bundles.size()),
      benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}

// Materials 0-3, wall time with both cores' CPU, median of 3.
void PerMaterial(benchmark::internal::Benchmark* b) {
  b->ArgName("material")
      ->DenseRange(0, 3)
      ->Unit(benchmark::kMillisecond)
      ->MeasureProcessCPUTime()
      ->UseRealTime()
      ->Repetitions(3)
      ->ReportAggregatesOnly(true);
}

// The robust default (blending/robust_solver.h) per frame of a sequence
// (the noise estimate, the ridge and on a take the temporal steps are per
// sequence), with the default index pruning (quality 0.2, edges <= 6 mm).
// material (Base::Material): 0 the 24 combinations, 1 with 0.5 mm marker
// noise (most bundles then fall outside their clouds, and lgi's projection
// searches cost more), 2 the 48-frame performance (a take), 3 with noise.
// Counter s_per_frame = sequence time / frames; compare with
// BM_BoundedSequence on the same material (issue 23: within 2x).
void BM_RobustSequence(benchmark::State& state) {
  Base& base = GetBase();
  Variant& v = GetVariant(200, 6, 24, 8);
  BlendshapeOptions bounded;
  bounded.bounded = true;
  const BlendshapeSolver global(base.actor.neutral, base.data, bounded);
  RobustSolver robust(base.actor.neutral, base.data, *v.solver, base.nn,
                      global, SolveOptions(), RobustOptions());
  RobustReport report;
  SolveMaterial(state, [&](const std::vector<BundleFrame>& frames,
                           const std::vector<JawPose>& jaw) {
    return robust.SolveSequence(frames, jaw, {}, &report);
  });
  state.counters["local_fraction"] =
      static_cast<double>(report.bundles_local) /
      std::max<int64_t>(1, report.bundles_local + report.bundles_global);
}
BENCHMARK(BM_RobustSequence)->Apply(PerMaterial);

// The bounded blendshape fit (`--method blendshape-bounded`) on the same
// material: the per-frame reference of issue 23's "within 2x".
void BM_BoundedSequence(benchmark::State& state) {
  Base& base = GetBase();
  BlendshapeOptions bounded;
  bounded.bounded = true;
  const BlendshapeSolver solver(base.actor.neutral, base.data, bounded);
  SolveMaterial(state, [&](const std::vector<BundleFrame>& frames,
                           const std::vector<JawPose>& jaw) {
    return solver.SolveSequence(frames, jaw);
  });
}
BENCHMARK(BM_BoundedSequence)->Apply(PerMaterial);

void BM_Blend(benchmark::State& state) {
  Base& base = GetBase();
  Variant& v = GetVariant(100, 8, 24, 8);
  FrameSolve frame = v.solver->SolveFrame(base.combos.bundles[0],
                                          base.combos.jaw[0].pose, nullptr);
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
