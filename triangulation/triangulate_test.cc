#include "triangulation/triangulate.h"

#include <cmath>
#include <random>
#include <set>

#include <gtest/gtest.h>

#include "core/error.h"
#include "core/temp_dir.h"
#include "synth/helmet_rig.h"
#include "synth/lens_test_rigs.h"

namespace hmc {
namespace {

// Points where a face would be, in front of the synthetic rig (helmet space).
struct Scene {
  HelmetRig rig;
  std::vector<BundleFrame> truth;
  std::vector<Track2d> tracks;  // exact projections where in both images
};

Scene MakeScene(uint64_t seed, int frames, int markers,
                const HelmetRigOptions& rig_options = HelmetRigOptions()) {
  Scene s;
  s.rig = MakeHelmetRig(rig_options, 100, 95);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> ux(-55, 55), uy(-105, 35), uz(40, 105);
  for (int f = 1; f <= frames; ++f) {
    BundleFrame bf;
    bf.frame = f;
    for (int m = 0; m < markers; ++m) {
      const std::string name = "m" + std::to_string(m);
      const Vec3 p(ux(rng), uy(rng), uz(rng));
      std::vector<Track2d> views;
      for (const HelmetCamera& hc : s.rig.cameras) {
        Vec2 pixel;
        if (hc.camera.Project(hc.cam_from_helmet * p, &pixel) && hc.camera.IsInImage(pixel)) {
          views.push_back({f, hc.name, name, pixel, 1});
        }
      }
      if (views.size() < 2) continue;
      bf.bundles[name] = p;
      for (Track2d& t : views) s.tracks.push_back(t);
    }
    s.truth.push_back(bf);
  }
  return s;
}

TEST(TriangulateTest, ExactProjectionsGiveTheTruth) {
  for (uint64_t seed : {1, 2, 3}) {
    const Scene s = MakeScene(seed, 5, 60);
    const TriangulateOutput out = RunTriangulate({&s.rig, &s.tracks, "tracks"}, {});
    const TriangulationAccuracy a = EvaluateTriangulation(out.bundles, s.truth, {}, 2);
    ASSERT_GT(a.compared, 200) << "seed " << seed;
    EXPECT_EQ(out.summary.triangulated, out.summary.candidates) << "seed " << seed;
    EXPECT_LT(a.max_mm, 1e-6) << "seed " << seed;
    EXPECT_LT(out.summary.max_residual_px, 1e-6) << "seed " << seed;
  }
}

// Issue 44, item 5: the same through a narrow pinhole radial-tangential
// lens and a double-sphere fisheye (unprojection and the Jet Jacobians of
// the refinement go through the camera's model).
TEST(TriangulateTest, ExactProjectionsGiveTheTruthThroughEveryLensModel) {
  for (const HelmetRigOptions& options : OtherLensRigOptions()) {
    const Scene s = MakeScene(4, 5, 60, options);
    const TriangulateOutput out = RunTriangulate({&s.rig, &s.tracks, "tracks"}, {});
    const TriangulationAccuracy a = EvaluateTriangulation(out.bundles, s.truth, {}, 2);
    ASSERT_GT(a.compared, 150) << options.model;
    EXPECT_EQ(out.summary.triangulated, out.summary.candidates) << options.model;
    EXPECT_LT(a.max_mm, 1e-6) << options.model;
    EXPECT_LT(out.summary.max_residual_px, 1e-6) << options.model;
  }
}

TEST(TriangulateTest, DepthUncertaintyMatchesTheErrorUnderNoise) {
  const double noise_px = 0.3;
  for (uint64_t seed : {4, 5}) {
    Scene s = MakeScene(seed, 10, 60);
    std::mt19937_64 rng(seed + 100);
    std::normal_distribution<double> noise(0, noise_px);
    for (Track2d& t : s.tracks) t.pixel += Vec2(noise(rng), noise(rng));
    TriangulateOptions options;
    options.noise_px = noise_px;
    const TriangulateOutput out = RunTriangulate({&s.rig, &s.tracks, "tracks"}, options);
    // The error along the first view's ray, in units of the predicted sigma:
    // about unit variance if the uncertainty is right.
    double sum_sq = 0;
    int n = 0;
    for (const TriangulationRecord& r : out.records) {
      if (r.status != TriangulationStatus::kOk) continue;
      const Vec3& truth = s.truth[r.frame - 1].bundles.at(r.marker);
      const HelmetCamera& hc = s.rig.cameras[0];
      const Vec3 centre = hc.cam_from_helmet.inverse().translation();
      const Vec3 d = (r.p_in_helmet - centre).normalized();
      const double z = d.dot(r.p_in_helmet - truth) / r.depth_sigma_mm;
      sum_sq += z * z;
      ++n;
    }
    ASSERT_GT(n, 400);
    const double ratio = std::sqrt(sum_sq / n);
    EXPECT_GT(ratio, 0.7) << "seed " << seed;
    EXPECT_LT(ratio, 1.4) << "seed " << seed;
  }
}

TEST(TriangulateTest, SwappedLabelIsGatedOut) {
  Scene s = MakeScene(7, 1, 40);
  // Swap the cam1 pixels of two markers that differ most across the
  // cameras' vertical baseline's epipolar direction (horizontally in cam1).
  std::vector<int> cam1;
  for (size_t i = 0; i < s.tracks.size(); ++i) {
    if (s.tracks[i].camera == "cam1") cam1.push_back(static_cast<int>(i));
  }
  int a = cam1[0], b = cam1[1];
  for (int i : cam1) {
    for (int j : cam1) {
      if (std::abs(s.tracks[i].pixel.x() - s.tracks[j].pixel.x()) >
          std::abs(s.tracks[a].pixel.x() - s.tracks[b].pixel.x())) {
        a = i;
        b = j;
      }
    }
  }
  std::swap(s.tracks[a].pixel, s.tracks[b].pixel);
  const TriangulateOutput out = RunTriangulate({&s.rig, &s.tracks, "tracks"}, {});
  EXPECT_EQ(out.summary.gated, 2);
  EXPECT_EQ(out.summary.triangulated, out.summary.candidates - 2);
  for (const TriangulationRecord& r : out.records) {
    const bool swapped = r.marker == s.tracks[a].marker || r.marker == s.tracks[b].marker;
    EXPECT_EQ(r.status == TriangulationStatus::kGated, swapped) << r.marker;
  }
  const TriangulationAccuracy acc = EvaluateTriangulation(out.bundles, s.truth, {}, 2);
  EXPECT_LT(acc.max_mm, 1e-6);
}

// Dots cut in both views (by the lip line, an eyelid) have centroids biased
// each its own way: well inside the gate, but their rays miss by more than
// the noise. The consistency test must catch most of them, estimate the
// noise, and spare the rest at about its false-rejection rate.
TEST(TriangulateTest, ConsistencyTestDropsBiasedViewsAndEstimatesTheNoise) {
  const double noise_px = 0.1;
  for (uint64_t seed : {11, 12, 13}) {
    Scene s = MakeScene(seed, 20, 60);
    std::mt19937_64 rng(seed + 200);
    std::normal_distribution<double> noise(0, noise_px);
    std::uniform_real_distribution<double> unit(0, 1);
    std::set<std::pair<int, std::string>> biased;
    for (Track2d& t : s.tracks) {
      t.pixel += Vec2(noise(rng), noise(rng));
      // cam1 of every 20th marker-frame: 1 px across the (vertical)
      // baseline's epipolar lines, i.e. horizontally.
      if (t.camera == "cam1" && unit(rng) < 0.05) {
        t.pixel.x() += unit(rng) < 0.5 ? 1.0 : -1.0;
        biased.insert({t.frame, t.marker});
      }
    }
    ASSERT_GT(biased.size(), 20u);
    const TriangulateOutput out = RunTriangulate({&s.rig, &s.tracks, "tracks"}, {});
    EXPECT_EQ(out.summary.gated, 0) << "seed " << seed;
    EXPECT_NEAR(out.summary.pixel_noise_px, noise_px, 0.2 * noise_px) << "seed " << seed;
    int caught = 0, spared_clean = 0, clean = 0;
    for (const TriangulationRecord& r : out.records) {
      const bool bad = biased.count({r.frame, r.marker}) > 0;
      const bool rejected = r.status == TriangulationStatus::kInconsistent;
      caught += bad && rejected;
      clean += !bad;
      spared_clean += !bad && !rejected;
    }
    EXPECT_EQ(out.summary.inconsistent, caught + clean - spared_clean) << "seed " << seed;
    EXPECT_GE(caught, 0.9 * biased.size()) << "seed " << seed;
    EXPECT_GE(spared_clean, 0.99 * clean) << "seed " << seed;
    TriangulateOptions off;
    off.consistency_p = 0;
    const TriangulateOutput all = RunTriangulate({&s.rig, &s.tracks, "tracks"}, off);
    EXPECT_EQ(all.summary.inconsistent, 0);
    EXPECT_EQ(all.summary.pixel_noise_px, 0);
    const TriangulationAccuracy with = EvaluateTriangulation(out.bundles, s.truth, {}, 2);
    const TriangulationAccuracy without = EvaluateTriangulation(all.bundles, s.truth, {}, 2);
    EXPECT_LT(with.rms_mm, without.rms_mm) << "seed " << seed;
  }
}

TEST(TriangulateTest, MonoMarkersBecomeRaysThroughTheTruth) {
  Scene s = MakeScene(8, 2, 30);
  // Drop cam1's view of every third marker.
  std::vector<Track2d> tracks;
  std::set<std::pair<int, std::string>> mono;
  for (const Track2d& t : s.tracks) {
    const bool drop = t.camera == "cam1" && std::stoi(t.marker.substr(1)) % 3 == 0;
    if (drop) {
      mono.insert({t.frame, t.marker});
      continue;
    }
    tracks.push_back(t);
  }
  ASSERT_GT(mono.size(), 5u);
  const TriangulateOutput out = RunTriangulate({&s.rig, &tracks, "tracks"}, {});
  ASSERT_EQ(out.rays.size(), mono.size());
  TempDir dir;
  const auto path = dir.path() / "rays.csv";
  WriteRaysCsv(path, out.rays);
  const std::vector<MonoRay> rays = ReadRaysCsv(path);
  ASSERT_EQ(rays.size(), mono.size());
  for (const MonoRay& ray : rays) {
    EXPECT_TRUE(mono.count({ray.frame, ray.marker}));
    EXPECT_EQ(ray.camera, "cam0");
    for (const BundleFrame& bf : out.bundles) EXPECT_FALSE(bf.frame == ray.frame && bf.bundles.count(ray.marker));
    const Vec3& truth = s.truth[ray.frame - 1].bundles.at(ray.marker);
    const Vec3 v = truth - ray.origin_in_helmet;
    EXPECT_GT(v.dot(ray.direction_in_helmet), 0);
    EXPECT_LT((v - v.dot(ray.direction_in_helmet) * ray.direction_in_helmet).norm(), 1e-6);
  }
}

TEST(TriangulateTest, UnknownCameraIsRefusedNamingTheFile) {
  Scene s = MakeScene(9, 1, 5);
  s.tracks[0].camera = "cam7";
  try {
    RunTriangulate({&s.rig, &s.tracks, "my_tracks.csv"}, {});
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("my_tracks.csv"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("cam7"), std::string::npos);
  }
}

}  // namespace
}  // namespace hmc
