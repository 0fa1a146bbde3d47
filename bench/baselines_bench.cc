// Per-frame cost of the baselines (blending/baseline_*.h) on the default
// synthetic actor, to set beside lgi's per-frame solve (bench/solve_bench.cc)
// in the same run: precompute (once per actor) and per-frame solve (weights
// or spline coefficients, blend over every vertex, jaw skinning). Frames:
// mixtures of two dataset shapes under the mean of their jaw poses, as in
// solve_bench. A second argument drops every n-th marker (0 = none), which
// forces blendshape to downdate its normal matrix and interp to factor a new
// system. Report the median of the repetitions. Results: docs/PERFORMANCE.md.
#include <benchmark/benchmark.h>

#include <random>

#include "bench/bench_util.h"
#include "blending/baseline_blendshape.h"
#include "blending/baseline_interp.h"
#include "core/jaw.h"

namespace hmc {
namespace {

struct Base {
  Base() : actor(DefaultActor()) {
    data = ComputeShapeData(actor);
    std::mt19937 rng(7);
    const int N = data.num_shapes, V = actor.NumVertices();
    for (int f = 0; f < 16; ++f) {
      const int a = rng() % N, b = rng() % N;
      MatX3d x = actor.neutral.V;
      for (int v = 0; v < V; ++v) {
        const float* da = data.Displacement(v, a);
        const float* db = data.Displacement(v, b);
        for (int i = 0; i < 3; ++i) {
          x(v, i) += 0.5 * ((da ? da[i] : 0.0f) + (db ? db[i] : 0.0f));
        }
      }
      JawPose pose;
      pose.open_deg =
          0.5 * (actor.shapes[a].jaw.open_deg + actor.shapes[b].jaw.open_deg);
      if (actor.jaw_rig) x = Skin(*actor.jaw_rig, pose, x);
      frames.push_back(BundlesOnMesh(data, actor.neutral.F, x, f + 1));
      jaw.push_back(pose);
    }
  }
  std::vector<BundleFrame> Frames(int drop_every) const {
    std::vector<BundleFrame> out = frames;
    if (drop_every <= 0) return out;
    for (BundleFrame& f : out) {
      for (int k = 0; k < data.num_bundles; k += drop_every) {
        f.bundles.erase(data.bundle_names[k]);
      }
    }
    return out;
  }
  const Actor& actor;
  ShapeData data;
  std::vector<BundleFrame> frames;
  std::vector<JawPose> jaw;
};

const Base& GetBase() {
  static const Base base;
  return base;
}

void Counters(benchmark::State& state, const Base& b) {
  state.counters["vertices"] = b.data.num_vertices;
  state.counters["shapes"] = b.data.num_shapes;
  state.counters["bundles"] = b.data.num_bundles;
}

void BM_BlendshapePrecompute(benchmark::State& state) {
  const Base& b = GetBase();
  BlendshapeOptions options;
  for (auto _ : state) {
    BlendshapeSolver solver(b.actor.neutral, b.data, options);
    benchmark::DoNotOptimize(&solver);
  }
  Counters(state, b);
}

void BlendshapeFrame(benchmark::State& state, bool bounded) {
  const Base& b = GetBase();
  BlendshapeOptions options;
  options.bounded = bounded;
  const BlendshapeSolver solver(b.actor.neutral, b.data, options);
  const std::vector<BundleFrame> frames = b.Frames(state.range(0));
  size_t f = 0;
  for (auto _ : state) {
    Eigen::VectorXd w;
    MatX3d mesh;
    const FrameSolve fs = solver.SolveFrame(frames[f], b.jaw[f], &w, &mesh);
    benchmark::DoNotOptimize(fs.ok);
    f = (f + 1) % frames.size();
  }
  Counters(state, b);
}
void BM_BlendshapeFrame(benchmark::State& state) {
  BlendshapeFrame(state, false);
}
void BM_BlendshapeBoundedFrame(benchmark::State& state) {
  BlendshapeFrame(state, true);
}

void BM_BlendshapeWeightsOnly(benchmark::State& state) {
  const Base& b = GetBase();
  const BlendshapeSolver solver(b.actor.neutral, b.data, BlendshapeOptions());
  size_t f = 0;
  for (auto _ : state) {
    Eigen::VectorXd w;
    const FrameSolve fs = solver.SolveFrame(b.frames[f], b.jaw[f], &w, nullptr);
    benchmark::DoNotOptimize(fs.ok);
    f = (f + 1) % b.frames.size();
  }
  Counters(state, b);
}

void BM_InterpPrecompute(benchmark::State& state) {
  const Base& b = GetBase();
  for (auto _ : state) {
    InterpSolver solver(b.actor.neutral, b.data, InterpOptions());
    benchmark::DoNotOptimize(&solver);
  }
  Counters(state, b);
}

void BM_InterpFrame(benchmark::State& state) {
  const Base& b = GetBase();
  const InterpSolver solver(b.actor.neutral, b.data, InterpOptions());
  const std::vector<BundleFrame> frames = b.Frames(state.range(0));
  size_t f = 0;
  for (auto _ : state) {
    MatX3d mesh;
    const FrameSolve fs = solver.SolveFrame(frames[f], b.jaw[f], &mesh);
    benchmark::DoNotOptimize(fs.ok);
    f = (f + 1) % frames.size();
  }
  Counters(state, b);
}

BENCHMARK(BM_BlendshapePrecompute)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_BlendshapeFrame)->Arg(0)->Arg(10)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_BlendshapeBoundedFrame)
    ->Arg(0)
    ->Arg(10)
    ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_BlendshapeWeightsOnly)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_InterpPrecompute)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_InterpFrame)->Arg(0)->Arg(10)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace hmc

BENCHMARK_MAIN();
