// Absolute accuracy on held-out material: the default solve (`robust`) on
// frames that activate action units the actor's dataset does not contain
// (synth/truth_frames.h, kind heldout), measured as `hmc eval` measures it
// (eval/eval_metrics.h), must stay within a stated bound in mm.
//
// Seeds 21-23: the method's choices were made on seeds 1-3 (docs/method.md),
// never on these. The bound (BOUND_NOTE below) was set once from seeds
// 21-26 of this setup and is not to be widened to make the test pass: a
// change that moves the error past it is a loss of accuracy to explain.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "blending/solve_method.h"
#include "eval/eval_metrics.h"
#include "synth/face_model.h"
#include "synth/synth_actor.h"
#include "synth/truth_frames.h"

namespace hmc {
namespace {

// BOUND_NOTE: on seeds 21-26 of this setup the robust solve measured a
// face mean of 0.006-0.043 mm and a face p95 of 0.016-0.26 mm (the small
// actor's held-out unit moves the skin by a few mm); the bounds are about
// twice the worst of them.
constexpr double kFaceMeanBoundMm = 0.1;
constexpr double kFaceP95BoundMm = 0.5;

struct HeldOutResult {
  double face_mean = 0, face_p95 = 0;  // mm
  double interp_face_mean = 0;         // the smooth baseline (mm)
};

HeldOutResult SolveHeldOut(int seed) {
  SynthActorOptions synth;
  synth.seed = seed;
  synth.grid_u = 48;
  synth.grid_v = 40;
  synth.dataset_inbetweens = false;
  synth.dataset_combos = false;
  synth.holdout = 1;
  const FaceModel model(synth);
  const Actor actor = SynthesizeActorFromModel(model, synth);
  TruthFramesOptions to;
  to.kind = "heldout";
  to.frames = 6;
  to.seed = seed;
  const TruthFrames truth = MakeTruthFrames(
      model, actor.markers, PlanDataset(model, synth), to);
  std::vector<JawPose> jaw;
  std::vector<int> numbers;
  for (const JawFrame& j : truth.jaw) {
    jaw.push_back(j.pose);
    numbers.push_back(j.frame);
  }
  MethodOptions options;
  options.build.nn.uv_resolution = 256;
  MethodSolvers solvers(actor, options, IndexCacheWrite::kNone);
  const SequenceEvaluator evaluator(actor, MeshMetricsOptions());
  HeldOutResult r;
  const SolveResult robust = solvers.Solve("robust", truth.bundles, jaw);
  const SequenceMetrics m = evaluator.Evaluate(truth.positions, robust.meshes,
                                               numbers, &truth.bundles);
  r.face_mean = m.face.mean;
  r.face_p95 = m.face.p95;
  const SolveResult interp = solvers.Solve("interp", truth.bundles, jaw);
  r.interp_face_mean = evaluator
                           .Evaluate(truth.positions, interp.meshes, numbers,
                                     &truth.bundles)
                           .face.mean;
  return r;
}

class HeldOutAccuracy : public ::testing::TestWithParam<int> {};

TEST_P(HeldOutAccuracy, RobustStaysWithinTheStatedBound) {
  const HeldOutResult r = SolveHeldOut(GetParam());
  std::printf("seed %d: robust face mean %.4f mm, p95 %.4f mm; interp face "
              "mean %.4f mm\n",
              GetParam(), r.face_mean, r.face_p95, r.interp_face_mean);
  EXPECT_LE(r.face_mean, kFaceMeanBoundMm);
  EXPECT_LE(r.face_p95, kFaceP95BoundMm);
}

INSTANTIATE_TEST_SUITE_P(UntunedSeeds, HeldOutAccuracy,
                         ::testing::Values(21, 22, 23));

}  // namespace
}  // namespace hmc
