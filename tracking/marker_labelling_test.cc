// The labelling at the reference frame (tracking/marker_labelling.cc) on an
// artist-style (broad) rig with a strong expression at that frame: the
// detections are the exact projections of the expressed face's markers
// (plus noise), so what is tested is the registration and the naming, not
// the detector; the names are checked against the synthetic truth.
#include <algorithm>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "core/mesh.h"
#include "synth/face_model.h"
#include "synth/footage_shot.h"
#include "synth/helmet_rig.h"
#include "synth/synth_actor.h"
#include "tracking/marker_tracker.h"

namespace hmc {
namespace {

struct LabellingScore {
  int visible = 0;  // dot-views given to the tracker
  int named = 0;    // named with their own marker's name
  int wrong = 0;    // named with another marker's name
};

// A broad-rig actor (small grid) whose reference frame holds the jaw
// dropped and three other units at 0.6-1 (a brow raise up to the hairline,
// a smile up to the lids: they move the markers the rigid registration
// relies on), the head 4 mm and 3 degrees off rest in the helmet.
struct ReferenceFrame {
  Actor actor;
  HelmetRig rig;
  std::vector<std::vector<DotDetection>> detections;  // per camera
  std::vector<std::vector<int>> marker_of;            // per camera and detection
};

ReferenceFrame StrongExpressionFrame(int seed) {
  SynthActorOptions options;
  options.seed = seed;
  options.grid_u = 32;
  options.grid_v = 25;
  options.rig = "broad";
  const FaceModel model(options);
  const Actor actor = SynthesizeActorFromModel(model, options);
  const HelmetRig rig = MakeShotRig(model, HelmetRigOptions());

  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> strength(0.6, 1.0);
  Eigen::VectorXd activations = model.ZeroActivations();
  activations[model.FindUnit("AU26_jaw_drop")] = strength(rng);
  std::vector<int> others;
  for (int u = 0; u < model.NumUnits(); ++u) {
    if (!model.units()[u].drives_jaw) others.push_back(u);
  }
  std::shuffle(others.begin(), others.end(), rng);
  for (int i = 0; i < 3; ++i) activations[others[i]] = strength(rng);
  const MatX3d face = model.Evaluate(activations);
  const MatX3d normals = VertexNormals(face, actor.neutral.F);

  std::normal_distribution<double> unit(0, 1);
  const Vec3 axis = Vec3(unit(rng), unit(rng), unit(rng)).normalized();
  const Vec3 shift = Vec3(unit(rng), unit(rng), unit(rng)).normalized();
  Rigid3 helmet_from_head = Rigid3::Identity();
  helmet_from_head.linear() = Eigen::AngleAxisd(3 * M_PI / 180, axis).toRotationMatrix();
  helmet_from_head.translation() = 4 * shift;

  // Per camera the markers' dots (the exact projection, 0.05 px noise),
  // shuffled; 3 % left out as if hidden.
  std::normal_distribution<double> noise(0, 0.05);
  std::uniform_real_distribution<double> u01(0, 1);
  std::vector<std::vector<DotDetection>> detections(2);
  std::vector<std::vector<int>> marker_of(2);
  for (int c = 0; c < 2; ++c) {
    const HelmetCamera& hc = rig.cameras[c];
    std::vector<int> order(actor.markers.size());
    for (size_t k = 0; k < order.size(); ++k) order[k] = static_cast<int>(k);
    std::shuffle(order.begin(), order.end(), rng);
    for (const int k : order) {
      const Marker& m = actor.markers[k];
      const Vec3 p = hc.cam_from_helmet * (helmet_from_head *
                                           EvaluateSurfacePoint(m.point, actor.neutral.F, face));
      const Vec3 n = hc.cam_from_helmet.linear() * helmet_from_head.linear() *
                     EvaluateSurfacePoint(m.point, actor.neutral.F, normals).normalized();
      Vec2 pixel;
      if (n.dot(p.normalized()) > -0.15 || !hc.camera.Project(p, &pixel) ||
          !hc.camera.IsInImage(pixel) || u01(rng) < 0.03) {
        continue;
      }
      DotDetection d;
      d.pixel = pixel + Vec2(noise(rng), noise(rng));
      d.diameter_px = 8;
      d.contrast = 0.5;
      d.score = 1;
      detections[c].push_back(d);
      marker_of[c].push_back(k);
    }
  }

  return {actor, rig, detections, marker_of};
}

LabellingScore LabelStrongExpression(int seed) {
  const ReferenceFrame frame = StrongExpressionFrame(seed);
  const std::vector<std::vector<DotDetection>>& detections = frame.detections;
  const std::vector<std::vector<int>>& marker_of = frame.marker_of;
  MarkerTracker tracker(frame.rig, MakeMarkerLayout(frame.actor, MarkerTrackerOptions().neighbours),
                        MarkerTrackerOptions());
  const std::vector<CameraFrameTracks> out =
      tracker.Start(detections, {cv::Mat(), cv::Mat()}, {8.0, 8.0});
  LabellingScore score;
  for (int c = 0; c < 2; ++c) {
    score.visible += static_cast<int>(detections[c].size());
    if (out.size() <= static_cast<size_t>(c)) continue;
    for (size_t i = 0; i < out[c].marker.size(); ++i) {
      // The detection named (its pixel is returned as given).
      int truth = -1;
      for (size_t d = 0; d < detections[c].size(); ++d) {
        if (detections[c][d].pixel == out[c].pixel[i]) truth = marker_of[c][d];
      }
      if (truth == out[c].marker[i]) {
        ++score.named;
      } else {
        ++score.wrong;
      }
    }
  }
  return score;
}

// Before the expression model entered the labelling, the rigid layout met
// such a frame with the chin dots 10-40 mm from their neutral places: the
// registration matched too few markers (no names at all) or named the
// lower face's dots after their neighbours.
TEST(MarkerLabellingTest, NamesAStrongBroadRigExpressionAtTheReferenceFrame) {
  for (int seed = 1; seed <= 3; ++seed) {
    const LabellingScore s = LabelStrongExpression(seed);
    const double named = static_cast<double>(s.named) / s.visible;
    const double wrong = s.named + s.wrong > 0 ? static_cast<double>(s.wrong) / (s.named + s.wrong) : 0.0;
    std::printf("seed %d: %d dot-views, %.1f %% named right, %d wrong names (%.2f %%)\n", seed,
                s.visible, 100 * named, s.wrong, 100 * wrong);
    ASSERT_GT(s.visible, 150) << "seed " << seed;
    // Measured: 99.6-100 % named, no wrong name, on seeds 1-12; before,
    // 56-71 % named with 3-8 % of the names wrong, or none at all.
    EXPECT_GE(named, 0.95) << "seed " << seed;
    EXPECT_LE(wrong, 0.005) << "seed " << seed;
  }
}

// The same frame seen through a calibration 2 mm / 1 degree off per camera
// (a nominal calibration.yaml not refined from the tags): the registration
// fails, and says why (issue 44, item 6) rather than naming dots wrongly.
TEST(MarkerLabellingTest, AnUncalibratedRigFailsNamingTheCalibrationAsTheLikelyCause) {
  for (int seed = 1; seed <= 2; ++seed) {
    const ReferenceFrame frame = StrongExpressionFrame(seed);
    const HelmetRig nominal = PerturbRig(frame.rig, 2, 1, 0, 100 + seed);
    MarkerTracker tracker(nominal,
                          MakeMarkerLayout(frame.actor, MarkerTrackerOptions().neighbours),
                          MarkerTrackerOptions());
    tracker.Start(frame.detections, {cv::Mat(), cv::Mat()}, {8.0, 8.0});
    const ReferenceLabelling& labelling = tracker.labelling();
    std::printf("seed %d: %s\n", seed, labelling.reason.c_str());
    EXPECT_FALSE(labelling.ok) << "seed " << seed;
    EXPECT_NE(labelling.reason.find("calibration's stereo pose is likely off"), std::string::npos)
        << labelling.reason;
  }
}

}  // namespace
}  // namespace hmc
