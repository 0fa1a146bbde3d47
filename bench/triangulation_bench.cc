// Speed of `hmc triangulate` and `hmc calibrate` excluding decoding (issue
// 20's target: >= 300 frames per second on 2 cores). Results and the
// command: docs/PERFORMANCE.md, "Triangulation and rig calibration".
//
// BM_Triangulate: RunTriangulate on 120 frames of the default rig with 155
// markers (noisy exact projections; ~40 % seen by both cameras, as on the
// default shot). Counter frames_per_s.
// BM_DetectTags: the tag detection of one sampled stereo frame (both
// cameras, rectified re-detection) on a rendered frame of the default actor.
// BM_SolveRig: the Ceres solve on 30 sampled frames of 4 tags x 2 cameras.
// `hmc calibrate` spends sample x BM_DetectTags + BM_SolveRig per shot.
#include <random>

#include <benchmark/benchmark.h>

#include "core/parallel.h"
#include "synth/footage.h"
#include "synth/footage_shot.h"
#include "synth/synth_actor.h"
#include "triangulation/rig_calibration.h"
#include "triangulation/triangulate.h"

namespace hmc {
namespace {

void BM_Triangulate(benchmark::State& state) {
  const HelmetRig rig = MakeHelmetRig(HelmetRigOptions(), 100, 95);
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> ux(-70, 70), uy(-110, 45), uz(30, 110);
  std::normal_distribution<double> noise(0, 0.1);
  std::vector<Track2d> tracks;
  const int frames = 120;
  for (int f = 1; f <= frames; ++f) {
    for (int m = 0; m < 155; ++m) {
      const Vec3 p(ux(rng), uy(rng), uz(rng));
      for (const HelmetCamera& hc : rig.cameras) {
        Vec2 pixel;
        if (hc.camera.Project(hc.cam_from_helmet * p, &pixel) && hc.camera.IsInImage(pixel)) {
          tracks.push_back({f, hc.name, "m" + std::to_string(m),
                            pixel + Vec2(noise(rng), noise(rng)), 1});
        }
      }
    }
  }
  TriangulateOutput out;
  for (auto _ : state) {
    out = RunTriangulate({&rig, &tracks, "bench"}, TriangulateOptions());
    benchmark::DoNotOptimize(out);
  }
  state.counters["frames_per_s"] =
      benchmark::Counter(static_cast<double>(frames) * state.iterations(),
                         benchmark::Counter::kIsRate);
  state.counters["bundles_per_frame"] = static_cast<double>(out.summary.triangulated) / frames;
}
BENCHMARK(BM_Triangulate)->Unit(benchmark::kMillisecond)->UseRealTime();

struct TagScene {
  TagScene() : model(synth), actor(SynthesizeActorFromModel(model, synth)) {
    rig = MakeShotRig(model, HelmetRigOptions());
    const FootageRenderer renderer(model.neutral(), model.face().st, actor.markers, rig,
                                   FootageRenderOptions(), 1);
    const MatX3d X = model.neutral().V;
    const SceneState s{&X, Rigid3::Identity()};
    for (int c = 0; c < renderer.NumCameras(); ++c) images.push_back(renderer.Render(c, {s}, 1).image);
  }
  SynthActorOptions synth;
  FaceModel model;
  Actor actor;
  HelmetRig rig;
  std::vector<cv::Mat> images;
};

void BM_DetectTags(benchmark::State& state) {
  static TagScene scene;
  const CalibrateOptions options;
  std::vector<std::unique_ptr<TagDetector>> detectors;
  for (size_t c = 0; c < scene.images.size(); ++c) {
    detectors.push_back(std::make_unique<TagDetector>(scene.rig.tag_family, options.tags));
  }
  int found = 0;
  for (auto _ : state) {
    std::vector<int> counts(scene.images.size());
    ParallelFor(0, static_cast<int64_t>(scene.images.size()), [&](int64_t c) {
      counts[c] = static_cast<int>(
          DetectRigTags(*detectors[c], scene.rig, 1, static_cast<int>(c), scene.images[c]).size());
    });
    found = counts[0] + counts[1];
  }
  state.counters["tags_found"] = found;
}
BENCHMARK(BM_DetectTags)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_SolveRig(benchmark::State& state) {
  const HelmetRig truth = MakeHelmetRig(HelmetRigOptions(), 100, 95);
  const HelmetRig nominal = PerturbRig(truth, 2, 1, 0, 1);
  std::mt19937_64 rng(2);
  std::normal_distribution<double> noise(0, 0.07);
  std::vector<TagObservation> observations;
  for (int f = 1; f <= 30; ++f) {
    for (size_t c = 0; c < truth.cameras.size(); ++c) {
      for (size_t t = 0; t < truth.tags.size(); ++t) {
        TagObservation o{f, static_cast<int>(c), static_cast<int>(t), {}};
        const std::vector<Vec3> corners = truth.tags[t].CornersInHelmet();
        for (int k = 0; k < 4; ++k) {
          truth.cameras[c].camera.Project(truth.cameras[c].cam_from_helmet * corners[k],
                                          &o.corners[k]);
          o.corners[k] += Vec2(noise(rng), noise(rng));
        }
        observations.push_back(o);
      }
    }
  }
  for (auto _ : state) {
    benchmark::DoNotOptimize(SolveRigFromTags(nominal, observations, CalibrateOptions()));
  }
}
BENCHMARK(BM_SolveRig)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace hmc

BENCHMARK_MAIN();
