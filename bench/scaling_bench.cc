// How the per-frame solve of lgi and of the blendshape baseline scales with
// the size of the problem, measured in one run so their ratio means
// something (issue 4; results and the command: docs/PERFORMANCE.md,
// "Scaling"). One frame = the whole per-frame solve through
// blending/solve_method.h (lgi: unskin, index query, choice, fill, blend,
// skin; blendshape: weights, blend, skin), run as a one-frame sequence of
// held-out random combinations (frames cycle over 8 of them).
//
//   BM_Shapes/<method>/<N>:   N dataset shapes on a 12,800-vertex actor: the
//                             first N of the synthetic dataset (108), beyond
//                             that random 3-shape mixtures of them
//                             (blendshape only: see below).
//   BM_Bundles/<method>/<K>:  K bundles on a 12,800-vertex actor: a subset of
//                             the 155 markers, beyond that extra markers on
//                             random face vertices near the existing ones.
//   BM_Vertices/<method>/<V>: grid_u x grid_v of the synthetic face.
//   BM_Threads/<method>/<T>:  the default actor with T threads (ThreadLimit).
//   BM_DatasetSize/<method>/<N>: N generator shapes (`hmc actor synth
//                             --shapes N`, 0 = the standard 108) on a
//                             7,680-vertex actor, index with
//                             max_edge_neighbours 24 (issue 25).
//   BM_DatasetSizeSequence/<method>/<N>: the same actors, a 48-frame
//                             performance solved as one sequence (counter
//                             frame_time: s per frame, the per-sequence work
//                             shared as in a shot).
// Counters setup_s: the setup's wall time (actor, frames; once per
// configuration); prepare_s: the method's first Prepare (lgi: the index).
// method: 0 = lgi, 1 = blendshape, 2 = robust (the default). Default options (indexing/index_options.h:
// the tetrahedra kept grow as the fourth power of the cloud size unless
// pruned by min_tet_quality / max_edge_mm). Setup (actor, index) is cached across
// iterations and benchmarks; counter peak_rss_mb = getrusage maxrss of the
// process so far (monotonic: read it per sweep, in order).
#include <benchmark/benchmark.h>

#include <map>
#include <memory>
#include <random>
#include <tuple>

#include "bench/bench_util.h"
#include "blending/solve_method.h"
#include "core/logging.h"
#include "core/parallel.h"
#include "synth/synth_actor.h"
#include "synth/truth_frames.h"

namespace hmc {
namespace {

constexpr int kSequenceFrames = 48;

struct Setup {
  Actor actor;
  std::unique_ptr<MethodSolvers> solvers;
  std::vector<BundleFrame> frames;
  std::vector<JawPose> jaw;
  // A performance of kSequenceFrames frames (BM_DatasetSizeSequence).
  std::vector<BundleFrame> sequence;
  std::vector<JawPose> sequence_jaw;
  double setup_s = 0;  // MakeSetup: the actor and the frames
  // Per method, the first Prepare (lgi: the index; robust after lgi: its
  // own precomputation only).
  std::map<std::string, double> prepare_s;
};

// Grid and size of a sweep; shapes/bundles < 0: as synthesised.
struct Config {
  int grid_u = 256, grid_v = 200;
  int shapes = -1, bundles = -1;
  int generator_shapes = 0;     // SynthActorOptions::shapes
  int max_edge_neighbours = 0;  // IndexOptions::max_edge_neighbours
  bool operator<(const Config& o) const {
    return std::tie(grid_u, grid_v, shapes, bundles, generator_shapes, max_edge_neighbours) <
           std::tie(o.grid_u, o.grid_v, o.shapes, o.bundles, o.generator_shapes,
                    o.max_edge_neighbours);
  }
};

std::unique_ptr<Setup> MakeSetup(const Config& c) {
  SynthActorOptions so;
  so.grid_u = c.grid_u;
  so.grid_v = c.grid_v;
  so.shapes = c.generator_shapes;
  const FaceModel model(so);
  auto s = std::make_unique<Setup>();
  s->actor = SynthesizeActorFromModel(model, so);
  Actor& actor = s->actor;
  std::mt19937 rng(5);
  if (c.shapes >= 0) {
    const std::vector<Shape> base = actor.shapes;
    actor.shapes.resize(std::min<size_t>(c.shapes, base.size()));
    std::uniform_int_distribution<int> pick(0, static_cast<int>(base.size()) - 1);
    std::uniform_real_distribution<double> t(0.2, 0.6);
    while (static_cast<int>(actor.shapes.size()) < c.shapes) {
      Shape shape;
      shape.name = "mix" + std::to_string(actor.shapes.size());
      shape.displacement = MatX3d::Zero(actor.NumVertices(), 3);
      for (int i = 0; i < 3; ++i) {
        const Shape& b = base[pick(rng)];
        const double w = t(rng);
        shape.displacement += w * b.displacement;
        shape.jaw.open_deg += w * b.jaw.open_deg;
      }
      actor.shapes.push_back(shape);
    }
  }
  if (c.bundles >= 0) {
    std::vector<Marker> markers = actor.markers;
    std::shuffle(markers.begin(), markers.end(), rng);
    const int existing = static_cast<int>(markers.size());
    markers.resize(std::min(c.bundles, existing));
    std::uniform_int_distribution<int> pick(0, existing - 1);
    std::uniform_int_distribution<int> corner(0, 2);
    while (static_cast<int>(markers.size()) < c.bundles) {
      // Beside an existing marker: a vertex of a neighbouring triangle.
      Marker m = actor.markers[pick(rng)];
      const int v = actor.neutral.F(m.point.face, corner(rng));
      m.name = "extra" + std::to_string(markers.size());
      m.vertex = v;
      m.point = SurfacePointAtVertex(actor.neutral.F, v);
      bool taken = false;
      for (const Marker& o : markers) taken |= o.point.face == m.point.face &&
                                               (o.point.bary - m.point.bary)
                                                       .norm() < 1e-9;
      if (!taken) markers.push_back(m);
    }
    actor.markers = markers;
  }
  MethodOptions options;
  options.build.index.max_edge_neighbours = c.max_edge_neighbours;
  s->solvers = std::make_unique<MethodSolvers>(actor, options, IndexCacheWrite::kNone);
  // Held-out random combinations of the (unmodified) generator, bundles on
  // the chosen markers.
  const std::vector<DatasetEntry> plan = PlanDataset(model, so);
  TruthFramesOptions to;
  to.kind = "combos";
  to.frames = 8;
  to.seed = 9;
  const TruthFrames truth = MakeTruthFrames(model, actor.markers, plan, to);
  s->frames = truth.bundles;
  s->jaw = JawPoses(truth.jaw);
  to.kind = "performance";
  to.frames = kSequenceFrames;
  const TruthFrames performance = MakeTruthFrames(model, actor.markers, plan, to);
  s->sequence = performance.bundles;
  s->sequence_jaw = JawPoses(performance.jaw);
  return s;
}

Setup& GetSetup(const Config& c) {
  static std::map<Config, std::unique_ptr<Setup>> cache;
  auto it = cache.find(c);
  if (it == cache.end()) {
    const StageTimer timer("bench setup");
    std::unique_ptr<Setup> setup = MakeSetup(c);
    setup->setup_s = timer.ElapsedSeconds();
    it = cache.emplace(c, std::move(setup)).first;
  }
  return *it->second;
}

const char* MethodName(int64_t m) {
  return m == 0 ? "lgi" : m == 1 ? "blendshape" : "robust";
}

void PrepareOnce(Setup& s, const std::string& method) {
  // Google Benchmark calls a benchmark more than once; the first Prepare
  // builds.
  if (!s.prepare_s.count(method)) {
    const StageTimer timer("prepare " + method);
    s.solvers->Prepare(method);
    s.prepare_s[method] = timer.ElapsedSeconds();
  }
}

void SetCounters(benchmark::State& state, Setup& s, const std::string& method) {
  state.SetLabel(method);
  state.counters["vertices"] = s.actor.NumVertices();
  state.counters["shapes"] = static_cast<double>(s.actor.shapes.size());
  state.counters["bundles"] = static_cast<double>(s.actor.markers.size());
  state.counters["peak_rss_mb"] = PeakRssMb();
  state.counters["setup_s"] = s.setup_s;
  state.counters["prepare_s"] = s.prepare_s[method];
}

void SolveFrames(benchmark::State& state, Setup& s, const std::string& method) {
  PrepareOnce(s, method);
  size_t f = 0;
  for (auto _ : state) {
    const SolveResult r =
        s.solvers->Solve(method, {s.frames[f]}, {s.jaw[f]});
    benchmark::DoNotOptimize(r.meshes.front().data());
    f = (f + 1) % s.frames.size();
  }
  SetCounters(state, s, method);
}

// One solve of the whole performance per iteration: the per-sequence work
// (robust: the noise, the shape prior, the correction's choice) is shared
// by its frames as in a shot. Counter frame_time: wall time per frame (s).
void SolveSequence(benchmark::State& state, Setup& s, const std::string& method) {
  PrepareOnce(s, method);
  for (auto _ : state) {
    const SolveResult r = s.solvers->Solve(method, s.sequence, s.sequence_jaw);
    benchmark::DoNotOptimize(r.meshes.front().data());
  }
  SetCounters(state, s, method);
  state.counters["frame_time"] = benchmark::Counter(
      static_cast<double>(s.sequence.size()),
      benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}

void BM_Shapes(benchmark::State& state) {
  Config c;
  c.grid_u = 128;
  c.grid_v = 100;
  c.shapes = static_cast<int>(state.range(1));
  SolveFrames(state, GetSetup(c), MethodName(state.range(0)));
}

void BM_Bundles(benchmark::State& state) {
  Config c;
  c.grid_u = 128;
  c.grid_v = 100;
  c.bundles = static_cast<int>(state.range(1));
  SolveFrames(state, GetSetup(c), MethodName(state.range(0)));
}

void BM_Vertices(benchmark::State& state) {
  Config c;
  const int v = static_cast<int>(state.range(1));
  // Grids of about v vertices with the default 1.28 aspect.
  c.grid_u = v <= 10000 ? 112 : v <= 51200 ? 256 : 512;
  c.grid_v = v <= 10000 ? 90 : v <= 51200 ? 200 : 400;
  SolveFrames(state, GetSetup(c), MethodName(state.range(0)));
}

// The actor of BM_DatasetSize*/<method>/<N>.
Config DatasetSizeConfig(const benchmark::State& state) {
  Config c;
  c.grid_u = 96;
  c.grid_v = 80;
  c.generator_shapes = static_cast<int>(state.range(1));
  c.max_edge_neighbours = 24;
  return c;
}

void BM_DatasetSize(benchmark::State& state) {
  SolveFrames(state, GetSetup(DatasetSizeConfig(state)), MethodName(state.range(0)));
}

void BM_DatasetSizeSequence(benchmark::State& state) {
  SolveSequence(state, GetSetup(DatasetSizeConfig(state)),
                MethodName(state.range(0)));
}

void BM_Threads(benchmark::State& state) {
  const ThreadLimit limit(static_cast<int>(state.range(1)));
  SolveFrames(state, GetSetup(Config()), MethodName(state.range(0)));
}

// lgi stops at the synthetic dataset's 108 shapes: with 400 shapes (292
// random mixtures) its index build (min_tet_quality 0.1, max_edge_mm 8)
// exceeded 20 GB and was killed; 200 was not attempted after that.
BENCHMARK(BM_Shapes)
    ->ArgsProduct({{0}, {25, 50, 108}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_Shapes)
    ->ArgsProduct({{1}, {25, 50, 108, 200, 400}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_Bundles)
    ->ArgsProduct({{0, 1}, {50, 100, 155, 300}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_Vertices)
    ->ArgsProduct({{0, 1}, {10000, 51200, 204800}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_DatasetSize)
    ->ArgsProduct({{0, 2}, {0, 250, 500, 1000}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_DatasetSizeSequence)
    ->ArgsProduct({{0, 2}, {0, 250, 500, 1000}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_Threads)
    ->ArgsProduct({{0, 1}, {1, 2}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace
}  // namespace hmc

BENCHMARK_MAIN();
