#include "synth/marker_layout.h"

#include <map>
#include <set>

#include <gtest/gtest.h>

#include "synth/face_model.h"
#include "synth/synth_actor.h"

namespace hmc {
namespace {

int CountTag(const std::vector<Marker>& markers, const std::string& tag) {
  int n = 0;
  for (const Marker& m : markers) n += m.HasTag(tag) ? 1 : 0;
  return n;
}

// Mean distance (mm, on the neutral) from each marker with `tag` to its
// nearest other marker: smaller = denser.
double MeanSpacing(const std::vector<Marker>& markers, const TriMesh& mesh,
                   const std::string& tag) {
  std::vector<Vec3> all;
  for (const Marker& m : markers) all.push_back(EvaluateSurfacePoint(m.point, mesh.F, mesh.V));
  double sum = 0;
  int count = 0;
  for (size_t i = 0; i < markers.size(); ++i) {
    if (!markers[i].HasTag(tag)) continue;
    double best = 1e9;
    for (size_t j = 0; j < markers.size(); ++j) {
      if (j != i) best = std::min(best, (all[i] - all[j]).norm());
    }
    sum += best;
    ++count;
  }
  return sum / count;
}

TEST(MarkerLayoutTest, RealisticCountsTagsAndDensity) {
  const FaceMesh face = BuildFaceMesh(DrawFaceProportions(1, 0.04), 256, 200);
  const std::vector<Marker> markers = LayoutMarkers(face, 1, 0.8);
  EXPECT_GE(markers.size(), 120u);
  std::set<std::string> names;
  for (const Marker& m : markers) EXPECT_TRUE(names.insert(m.name).second) << m.name;
  EXPECT_TRUE(names.count("mouth_upper_03"));
  EXPECT_GE(CountTag(markers, "stable"), 10);
  EXPECT_GE(CountTag(markers, "jaw"), 10);
  EXPECT_GE(CountTag(markers, "mouth"), 25);
  EXPECT_GE(CountTag(markers, "eye_l"), 8);
  EXPECT_GE(CountTag(markers, "eye_r"), 8);
  for (const std::string region : {"brow", "nose", "cheek_l", "cheek_r", "chin", "forehead"}) {
    EXPECT_GE(CountTag(markers, region), 5) << region;
  }
  // Every marker has a region tag besides stable / jaw.
  const std::set<std::string> regions = {"brow",    "eye_l",   "eye_r", "nose",
                                         "cheek_l", "cheek_r", "mouth", "chin",
                                         "jaw",     "forehead"};
  for (const Marker& m : markers) {
    bool has_region = false;
    for (const std::string& tag : m.tags) has_region |= regions.count(tag) > 0;
    EXPECT_TRUE(has_region) << m.name;
  }
  // Denser around the mouth and eyes than on the forehead and cheeks.
  const double mouth = MeanSpacing(markers, face.mesh, "mouth");
  const double eye = MeanSpacing(markers, face.mesh, "eye_l");
  const double forehead = MeanSpacing(markers, face.mesh, "forehead");
  const double cheek = MeanSpacing(markers, face.mesh, "cheek_l");
  EXPECT_LT(mouth, 0.75 * forehead);
  EXPECT_LT(eye, 0.75 * forehead);
  EXPECT_LT(mouth, 0.75 * cheek);
  RecordProperty("markers", std::to_string(markers.size()));
  for (const std::string tag : {"stable", "jaw", "mouth", "eye_l", "eye_r", "brow",
                                "forehead", "nose", "cheek_l", "chin"}) {
    RecordProperty("tag_" + tag, std::to_string(CountTag(markers, tag)));
  }
  RecordProperty("spacing_eye_mm", std::to_string(eye));
  RecordProperty("spacing_cheek_mm", std::to_string(cheek));
  RecordProperty("spacing_mouth_mm", std::to_string(mouth));
  RecordProperty("spacing_forehead_mm", std::to_string(forehead));
}

TEST(MarkerLayoutTest, OnTheSurfaceAtAnyResolution) {
  for (const auto& [gu, gv] : {std::pair{40, 32}, std::pair{64, 52}, std::pair{256, 200}}) {
    for (uint64_t seed : {1u, 2u, 3u}) {
      const FaceMesh face = BuildFaceMesh(DrawFaceProportions(seed, 0.04), gu, gv);
      const std::vector<Marker> markers = LayoutMarkers(face, seed, 0.8);
      for (const Marker& m : markers) {
        ASSERT_GE(m.point.face, 0) << m.name;
        ASSERT_LT(m.point.face, face.mesh.NumFaces()) << m.name;
        EXPECT_NEAR(m.point.bary.sum(), 1.0, 1e-12) << m.name;
        EXPECT_GE(m.point.bary.minCoeff(), -1e-12) << m.name;
      }
    }
  }
}

TEST(MarkerLayoutTest, JitterIsSeededAndSmall) {
  const FaceMesh face = BuildFaceMesh(DrawFaceProportions(1, 0.0), 128, 100);
  const auto a = LayoutMarkers(face, 5, 0.8), b = LayoutMarkers(face, 5, 0.8);
  const auto c = LayoutMarkers(face, 6, 0.8), exact = LayoutMarkers(face, 6, 0.0);
  ASSERT_EQ(a.size(), c.size());
  double max_move = 0, moved = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].point.face, b[i].point.face);
    EXPECT_EQ(a[i].point.bary, b[i].point.bary);
    const Vec3 pc = EvaluateSurfacePoint(c[i].point, face.mesh.F, face.mesh.V);
    const Vec3 pe = EvaluateSurfacePoint(exact[i].point, face.mesh.F, face.mesh.V);
    max_move = std::max(max_move, (pc - pe).norm());
    moved += (pc - pe).norm() > 0.05 ? 1 : 0;
  }
  EXPECT_GT(moved, 0.8 * a.size());
  // 2 std in the face plane, stretched a little by the surface's slope;
  // lip markers may step off the slit by half a row.
  EXPECT_LT(max_move, 6.0);
}

TEST(MarkerLayoutTest, StableMarkersBarelyMove) {
  SynthActorOptions options;
  options.grid_u = 128;
  options.grid_v = 100;
  const FaceModel model(options);
  const std::vector<Marker> markers = LayoutMarkers(model.face(), 1, 0.8);
  const std::vector<DatasetEntry> plan = PlanDataset(model, options);
  double stable_max = 0, other_mean = 0;
  std::map<std::string, double> other_max;
  for (const DatasetEntry& entry : plan) {
    const MatX3d x = model.Evaluate(entry.activations);
    for (const Marker& m : markers) {
      const double d = (EvaluateSurfacePoint(m.point, model.neutral().F, x) -
                        EvaluateSurfacePoint(m.point, model.neutral().F, model.neutral().V))
                           .norm();
      if (m.HasTag("stable")) {
        stable_max = std::max(stable_max, d);
      } else {
        other_max[m.name] = std::max(other_max[m.name], d);
      }
    }
  }
  for (const auto& [name, d] : other_max) other_mean += d / other_max.size();
  EXPECT_LT(stable_max, 1.5);
  EXPECT_GT(other_mean, 4.0 * stable_max);
  RecordProperty("stable_max_mm", std::to_string(stable_max));
}

}  // namespace
}  // namespace hmc
