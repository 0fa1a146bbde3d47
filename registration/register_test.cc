// `hmc register` on rendered neutral takes of a small synthetic actor with
// dots painted off their marker points (synth/paint.h): the registered
// points against the painted ones (painted_markers.csv), and the markers
// left unpainted reported. Half-size images, a few frames, so each take
// stays within seconds; the full-size measurement is docs/registration.md.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "core/day_markers.h"
#include "core/error_stats.h"
#include "core/temp_dir.h"
#include "registration/register.h"
#include "synth/face_model.h"
#include "synth/footage_shot.h"
#include "synth/synth_actor.h"

namespace hmc {
namespace {

namespace fs = std::filesystem;

struct Take {
  Actor package;
  Actor painted;  // the package with painted_markers.csv
  RegisterOutput output;
};

Take RegisterTake(const fs::path& dir, int seed, double jitter_mm, int missing) {
  SynthActorOptions actor_options;
  actor_options.seed = seed;
  actor_options.grid_u = 64;
  actor_options.grid_v = 52;
  actor_options.dataset_inbetweens = false;
  actor_options.dataset_combos = false;
  const FaceModel model(actor_options);
  WriteActor(SynthesizeActorFromModel(model, actor_options), dir / "actor", 17);
  Take take;
  take.package = LoadActor(dir / "actor");
  SynthShotOptions shot;
  shot.performance.frames = 6;
  shot.performance.seed = seed;
  shot.performance.expression_scale = 0;  // configs/synth_shot_neutral.yaml
  shot.performance.slip_mm = 1;
  shot.performance.slip_deg = 0.5;
  shot.rig.width = 640;  // half size, as tests/track_test.cc
  shot.rig.height = 512;
  shot.rig.focal_px = 350;
  shot.contact_frames = 0;
  shot.video = "png";
  shot.threads = 2;
  shot.paint.jitter_mm = jitter_mm;
  shot.paint.missing = missing;
  RunSynthShot(model, take.package, shot, dir / "shot");
  take.painted = WithDayMarkers(take.package, dir / "shot" / "painted_markers.csv");
  RegisterOptions options;
  options.track.threads = 2;
  take.output = RunRegister({dir / "shot", dir / "shot" / "calibration.yaml", dir / "actor",
                             dir / "work"},
                            options);
  return take;
}

// Registered minus painted point (mm) of every marker registered.
std::vector<double> Errors(const Take& take) {
  std::vector<double> errors;
  for (const RegisteredMarker& r : take.output.registered) {
    const int k = take.painted.FindMarker(r.name);
    EXPECT_GE(k, 0) << r.name << " registered but not painted";
    if (k < 0) continue;
    const Vec3 truth = EvaluateSurfacePoint(take.painted.markers[k].point,
                                            take.painted.neutral.F, take.painted.neutral.V);
    errors.push_back((r.position - truth).norm());
  }
  return errors;
}

// The targets (docs/registration.md): median 0.1 mm, p95 0.3 mm.
// Half-size images and 6 frames: the median holds; 87-93 % of the dots
// lie within 0.3 mm (measured on these seeds), the rest are dots painted
// 2-3 mm off that carry a neighbour's name or are seen at a grazing angle
// in one camera. At full size (docs/registration.md) the p95 holds.
constexpr double kMedianMm = 0.1;
constexpr double kP95Mm = 0.3;
constexpr double kWithinFraction = 0.85;

TEST(Register, RecoversPaintedOffsets) {
  for (const auto& [seed, jitter] : {std::pair{21, 0.5}, std::pair{34, 2.0}, std::pair{47, 3.0}}) {
    TempDir dir("hmc_register_test");
    const Take take = RegisterTake(dir.path(), seed, jitter, 0);
    std::vector<double> errors = Errors(take);
    // Most of the painted dots are found ...
    EXPECT_GE(errors.size(), 0.5 * take.painted.markers.size()) << "seed " << seed;
    // ... where they were painted, far closer than the paint is to the
    // package's markers (jitter per axis).
    const double median = UpperMedian(&errors);
    const double p95 = NearestRankPercentile(&errors, 0.95);
    std::printf("seed %d jitter %.1f: %zu of %zu registered, median %.3f p95 %.3f mm\n", seed,
                jitter, errors.size(), take.painted.markers.size(), median, p95);
    EXPECT_LT(median, kMedianMm) << "seed " << seed << " jitter " << jitter;
    const double within = std::count_if(errors.begin(), errors.end(),
                                         [](double e) { return e <= kP95Mm; });
    EXPECT_GE(within, kWithinFraction * errors.size())
        << "seed " << seed << " jitter " << jitter << ": p95 " << p95 << " mm";
  }
}

TEST(Register, ReportsAnUnpaintedMarker) {
  for (const int seed : {58, 69}) {
    TempDir dir("hmc_register_missing");
    const Take take = RegisterTake(dir.path(), seed, 1.5, 1);
    std::vector<std::string> unpainted;
    for (const Marker& m : take.package.markers) {
      if (take.painted.FindMarker(m.name) < 0) unpainted.push_back(m.name);
    }
    ASSERT_EQ(unpainted.size(), 1u);
    const auto& nf = take.output.not_found;
    EXPECT_NE(std::find(nf.begin(), nf.end(), unpainted[0]), nf.end())
        << unpainted[0] << " was not painted but not reported";
    for (const Marker& m : take.output.markers) EXPECT_NE(m.name, unpainted[0]);
  }
}

}  // namespace
}  // namespace hmc
