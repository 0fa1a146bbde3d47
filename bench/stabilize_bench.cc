// `hmc stabilize` and `hmc jaw` on the default synthetic actor: a 300-frame
// shot with the default slip (seed 1) and one with configs/synth_shot_slip.yaml's
// large slip and strong brow and jaw activity (seed 2), ground-truth bundles
// with 0 or 0.2 mm Gaussian noise per helmet coordinate. Times the whole
// RunStabilize / RunJaw (wall time, both cores: items_per_second is frames/s) and reports
// the errors against the truth as counters: head pose RMS (translation_mm,
// rotation_deg) and the same for plain unweighted Kabsch on the `stable`
// markers (kabsch_*), jaw RMS per parameter on the stabilized bundles.
// Args: shot (0 default, 1 slip), noise (micrometres), expression (0/1;
// the other options at their defaults, shot weights on).
// Results: docs/PERFORMANCE.md, docs/stabilization.md.
#include <map>
#include <tuple>

#include <benchmark/benchmark.h>

#include "stabilization/accuracy.h"
#include "stabilization/jaw_fit.h"
#include "stabilization/shot_test_util.h"
#include "stabilization/stabilize.h"

namespace hmc {
namespace {

const SmallActor& DefaultActor() {
  static const SmallActor actor = MakeTestActor(SynthActorOptions());
  return actor;
}

const ShotTruth& Shot(int shot, int noise_um) {
  static std::map<std::pair<int, int>, ShotTruth> cache;
  auto it = cache.find({shot, noise_um});
  if (it == cache.end()) {
    PerformanceOptions perf;
    perf.frames = 300;
    perf.seed = shot + 1;
    if (shot == 1) {
      perf.slip_mm = 10;
      perf.slip_deg = 5;
      perf.brow_activity = 0.8;
      perf.jaw_activity = 0.8;
    }
    it = cache.emplace(std::make_pair(shot, noise_um),
                       MakeShotTruth(DefaultActor(), perf, noise_um / 1000.0))
             .first;
  }
  return it->second;
}

void BM_Stabilize(benchmark::State& state) {
  const SmallActor& a = DefaultActor();
  const ShotTruth& shot = Shot(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  StabilizeOptions options;
  options.expression = state.range(2) != 0;
  StabilizeOutput out;
  for (auto _ : state) {
    out = RunStabilize(a.markers, shot.helmet, options);
    benchmark::DoNotOptimize(out.frames.data());
  }
  state.SetItemsProcessed(state.iterations() * static_cast<int64_t>(shot.helmet.size()));
  const PoseError error = ComparePoses(Poses(out.frames), shot.head_from_helmet);
  StabilizeOptions kabsch;
  kabsch.weighting = "tags";
  kabsch.loss = "none";
  const PoseError plain =
      ComparePoses(Poses(RunStabilize(a.markers, shot.helmet, kabsch).frames), shot.head_from_helmet);
  state.counters["translation_mm"] = error.translation_rms_mm;
  state.counters["rotation_deg"] = error.rotation_rms_deg;
  state.counters["kabsch_translation_mm"] = plain.translation_rms_mm;
  state.counters["kabsch_rotation_deg"] = plain.rotation_rms_deg;
}
BENCHMARK(BM_Stabilize)
    ->ArgsProduct({{0, 1}, {0, 200}, {0, 1}})
    ->ArgNames({"shot", "noise_um", "expression"})
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);

void BM_Jaw(benchmark::State& state) {
  const SmallActor& a = DefaultActor();
  const ShotTruth& shot = Shot(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  const StabilizeOutput stabilized = RunStabilize(a.markers, shot.helmet, StabilizeOptions());
  JawOptions options;
  JawOutput out;
  for (auto _ : state) {
    out = RunJaw(a.actor, a.markers, stabilized.bundles, options);
    benchmark::DoNotOptimize(out.frames.data());
  }
  state.SetItemsProcessed(state.iterations() * static_cast<int64_t>(shot.helmet.size()));
  const JawError error = CompareJaw(out.JawFrames(), shot.jaw);
  state.counters["open_deg"] = error.rms[0];
  state.counters["lateral_deg"] = error.rms[1];
  state.counters["protrude_mm"] = error.rms[2];
}
BENCHMARK(BM_Jaw)
    ->ArgsProduct({{0, 1}, {0, 200}})
    ->ArgNames({"shot", "noise_um"})
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace hmc

BENCHMARK_MAIN();
