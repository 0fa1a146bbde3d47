#include "blending/solve_method.h"

#include <gtest/gtest.h>

#include <random>

#include "core/error.h"
#include "core/jaw.h"
#include "indexing/lgi_test_actor.h"

namespace hmc {
namespace {

MethodOptions SmallOptions() {
  MethodOptions o;
  o.build.nn.uv_resolution = 256;
  return o;
}

BundleFrame Bundles(const Actor& actor, int frame, const MatX3d& x) {
  BundleFrame b;
  b.frame = frame;
  for (const Marker& m : actor.markers) {
    b.bundles[m.name] = EvaluateSurfacePoint(m.point, actor.neutral.F, x);
  }
  return b;
}

TEST(SolveMethod, UnknownNameListsTheValidOnes) {
  try {
    CheckSolveMethod("lgi_rbf", "--method");
    FAIL() << "no error";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("--method"), std::string::npos) << what;
    EXPECT_NE(what.find("'lgi_rbf'"), std::string::npos) << what;
    for (const std::string& name : SolveMethodNames()) {
      EXPECT_NE(what.find(name), std::string::npos) << name;
    }
  }
  for (const std::string& name : SolveMethodNames()) {
    EXPECT_NO_THROW(CheckSolveMethod(name, "--method"));
  }
}

TEST(SolveMethod, OptionsOfEveryMethodAreRegisteredInTheirGroups) {
  MethodOptions options;
  OptionFields fields;
  options.Register(&fields);
  for (const char* name :
       {"index.max_edge_mm", "nn.uv_resolution", "solve.smooth_window",
        "blendshape.penalty", "interp.merge_mm", "lgi_rbf.sigma_mm"}) {
    EXPECT_NE(fields.Find(name), nullptr) << name;
  }
  EXPECT_TRUE(options.Check());
  options.lgi_rbf.cutoff = 2.0;
  EXPECT_FALSE(options.Check());
}

// Every method on the same inputs: one mesh per frame, the frames' records,
// a bad frame repeating the previous good mesh, and the jaw-skinned neutral
// reproduced from its own bundles (every method can represent it exactly).
class EveryMethod : public ::testing::TestWithParam<int> {};

TEST_P(EveryMethod, SameContractOnTheSameInputs) {
  testing::LgiTestActorOptions ao;
  ao.seed = GetParam();
  const Actor actor = testing::MakeLgiTestActor(ao);
  const int V = actor.NumVertices(), K = static_cast<int>(actor.markers.size());
  std::mt19937 rng(GetParam());
  std::uniform_real_distribution<double> open(1.0, 8.0);
  std::vector<BundleFrame> frames;
  std::vector<JawPose> jaw(4);
  std::vector<MatX3d> neutral_skinned;
  for (int f = 0; f < 4; ++f) {
    jaw[f].open_deg = open(rng);
    neutral_skinned.push_back(Skin(*actor.jaw_rig, jaw[f], actor.neutral.V));
    if (f == 3) {
      const MatX3d x = actor.neutral.V + 0.5 * actor.shapes[0].displacement +
                       0.5 * actor.shapes[3].displacement;
      frames.push_back(Bundles(actor, f + 1, x));
    } else {
      frames.push_back(Bundles(actor, f + 1, neutral_skinned.back()));
    }
  }
  const std::vector<std::string> errors = {"", "", "no jaw pose", ""};
  MethodSolvers solvers(actor, SmallOptions(), IndexCacheWrite::kNone);
  for (const std::string& method : SolveMethodNames()) {
    SCOPED_TRACE(method);
    const SolveResult r = solvers.Solve(method, frames, jaw, errors);
    ASSERT_EQ(r.meshes.size(), frames.size());
    ASSERT_EQ(r.frames.size(), frames.size());
    EXPECT_EQ(r.summary.frames, 4);
    EXPECT_EQ(r.summary.bad_frames, 1);
    for (int f = 0; f < 4; ++f) {
      EXPECT_EQ(r.meshes[f].rows(), V);
      EXPECT_EQ(static_cast<int>(r.frames[f].bundles.size()), K);
      EXPECT_EQ(r.frames[f].ok, f != 2) << r.frames[f].reason;
    }
    EXPECT_EQ(r.frames[2].reason, "no jaw pose");
    EXPECT_EQ((r.meshes[2] - r.meshes[1]).cwiseAbs().maxCoeff(), 0.0);
    for (int f = 0; f < 2; ++f) {
      EXPECT_LT((r.meshes[f] - neutral_skinned[f]).cwiseAbs().maxCoeff(), 1e-6)
          << "frame " << f;
    }
  }
  ASSERT_NE(solvers.lgi_model(), nullptr);
  // lgi-rbf after lgi on the same inputs reuses its choices: same result as
  // on its own.
  MethodSolvers fresh(actor, SmallOptions(), IndexCacheWrite::kNone);
  const SolveResult alone = fresh.Solve("lgi-rbf", frames, jaw, errors);
  EXPECT_EQ(fresh.last_reused_seconds(), 0.0);
  solvers.Solve("lgi", frames, jaw, errors);
  const SolveResult reused = solvers.Solve("lgi-rbf", frames, jaw, errors);
  EXPECT_GT(solvers.last_reused_seconds(), 0.0);
  for (int f = 0; f < 4; ++f) {
    EXPECT_EQ((alone.meshes[f] - reused.meshes[f]).cwiseAbs().maxCoeff(), 0.0);
  }
  EXPECT_THROW(solvers.Solve("rbf", frames, jaw, errors), InputError);
}

INSTANTIATE_TEST_SUITE_P(Seeds, EveryMethod, ::testing::Values(1, 2));

}  // namespace
}  // namespace hmc
