// Tracking speed (docs/PERFORMANCE.md, "Tracking"): `hmc track`'s per-frame
// work on the default shot (1280 x 1024, default synthetic actor): FFV1
// decoding of both cameras, dot detection (both cameras in parallel) and
// labelling/tracking, over a 12-frame shot rendered once at start-up
// (~1 min). Counter: camera-frames per second (the target: 60).
//   build/bin/hmc_track_bench --benchmark_min_time=10
#include <filesystem>
#include <memory>

#include <benchmark/benchmark.h>
#include <unistd.h>

#include "core/actor.h"
#include "core/allocator.h"
#include "core/calibration.h"
#include "core/parallel.h"
#include "synth/face_model.h"
#include "synth/footage_shot.h"
#include "synth/synth_actor.h"
#include "tracking/dot_detector.h"
#include "tracking/footage_reader.h"
#include "tracking/marker_tracker.h"

namespace hmc {
namespace {

namespace fs = std::filesystem;

struct Fixture {
  fs::path dir;
  HelmetRig rig;
  MarkerLayout layout;
  std::vector<double> dot_size;
};

Fixture& Get() {
  static Fixture* fixture = [] {
    auto* f = new Fixture;
    f->dir = fs::temp_directory_path() / ("hmc_track_bench_" + std::to_string(getpid()));
    SynthActorOptions synth;
    const Actor actor = SynthesizeActor(synth);
    const FaceModel model(synth);
    SynthShotOptions options;
    options.performance.frames = 12;
    options.contact_frames = 0;
    RunSynthShot(model, actor, options, f->dir);
    f->rig = ReadCalibration(f->dir / "calibration.yaml");
    f->layout = MakeMarkerLayout(actor, MarkerTrackerOptions().neighbours);
    FootageReader reader(f->dir, {"cam0", "cam1"}, FootageOptions());
    FootageFrame frame;
    reader.Next(&frame);
    for (const cv::Mat& image : frame.images) {
      f->dot_size.push_back(MeasureDotSize(image, DotDetectorOptions()));
    }
    return f;
  }();
  return *fixture;
}

void BM_DecodeDetectTrack(benchmark::State& state) {
  ThreadLimit limit(static_cast<int>(state.range(0)));
  Fixture& f = Get();
  const DotDetectorOptions detect;
  int64_t views = 0;
  for (auto _ : state) {
    FootageReader reader(f.dir, {"cam0", "cam1"}, FootageOptions());
    MarkerTracker tracker(f.rig, f.layout, MarkerTrackerOptions());
    FootageFrame frame;
    bool started = false;
    while (reader.Next(&frame)) {
      std::vector<std::vector<DotDetection>> detections(2);
      ParallelFor(0, 2, [&](int64_t c) {
        detections[c] = DetectDots(frame.images[c], detect, f.dot_size[c]);
      });
      if (!started) {
        benchmark::DoNotOptimize(tracker.Start(detections, frame.images, f.dot_size));
        started = true;
      } else {
        benchmark::DoNotOptimize(tracker.Step(detections, frame.images));
      }
      views += 2;
    }
  }
  state.counters["camera_frames_per_s"] =
      benchmark::Counter(static_cast<double>(views), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_DecodeDetectTrack)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_DetectOneView(benchmark::State& state) {
  Fixture& f = Get();
  FootageReader reader(f.dir, {"cam0", "cam1"}, FootageOptions());
  FootageFrame frame;
  reader.Next(&frame);
  const DotDetectorOptions detect;
  for (auto _ : state) benchmark::DoNotOptimize(DetectDots(frame.images[0], detect, f.dot_size[0]));
  state.counters["views_per_s"] = benchmark::Counter(1, benchmark::Counter::kIsIterationInvariantRate);
}
BENCHMARK(BM_DetectOneView)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace hmc

// As `hmc` does (apps/main.cc): the allocator keeps freed frames for reuse.
int main(int argc, char** argv) {
  hmc::KeepFreedMemoryForReuse();
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
