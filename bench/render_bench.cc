// Footage rendering speed (docs/PERFORMANCE.md, "Footage rendering"): one
// stereo frame of the default shot (1280 x 1024, default 51200-vertex
// synthetic actor, default render options with noise and vignetting),
// geometry evaluation included, as `hmc synth shot` does per frame.
//   build/bin/hmc_render_bench --benchmark_min_time=5

#include <memory>

#include <benchmark/benchmark.h>

#include "core/allocator.h"
#include "core/parallel.h"
#include "synth/face_model.h"
#include "synth/footage.h"
#include "synth/footage_shot.h"
#include "synth/marker_layout.h"
#include "synth/performance.h"
#include "synth/synth_actor.h"

namespace hmc {
namespace {

struct Fixture {
  std::unique_ptr<FaceModel> model;
  std::unique_ptr<FootageRenderer> renderer;
  ShotPerformance performance;
};

Fixture& Get() {
  static Fixture* fixture = [] {
    KeepFreedMemoryForReuse();
    auto* f = new Fixture;
    SynthActorOptions synth;
    f->model = std::make_unique<FaceModel>(synth);
    const auto markers = LayoutMarkers(f->model->face(), 1, synth.marker_jitter_mm);
    SynthShotOptions options;
    const HelmetRig rig = MakeShotRig(*f->model, options.rig);
    f->renderer = std::make_unique<FootageRenderer>(f->model->neutral(), f->model->face().st,
                                                    markers, rig, options.render, 1);
    f->performance = MakePerformance(*f->model, options.performance);
    return f;
  }();
  return *fixture;
}

void BM_StereoFrame(benchmark::State& state) {
  ThreadLimit limit(static_cast<int>(state.range(0)));
  Fixture& f = Get();
  int frame = 0;
  for (auto _ : state) {
    const int i = frame++ % static_cast<int>(f.performance.activations.size());
    const MatX3d X = f.model->Evaluate(f.performance.activations[i]);
    const SceneState scene{&X, f.performance.head_from_helmet[i]};
    for (int c = 0; c < f.renderer->NumCameras(); ++c) {
      const ViewRender view = f.renderer->Render(c, {scene}, i * 2 + c);
      benchmark::DoNotOptimize(view.image.data);
      benchmark::DoNotOptimize(f.renderer->ProjectDots(c, scene, view));
    }
  }
  state.counters["stereo_fps"] =
      benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_StereoFrame)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace hmc

BENCHMARK_MAIN();
