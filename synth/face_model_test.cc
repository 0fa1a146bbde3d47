#include "synth/face_model.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <set>
#include <vector>

#include <gtest/gtest.h>

#include "core/parallel.h"
#include "synth/synth_actor.h"

namespace hmc {
namespace {

SynthActorOptions SmallOptions(int seed = 1) {
  SynthActorOptions options;
  options.seed = seed;
  options.grid_u = 96;
  options.grid_v = 80;
  return options;
}

// Detail tests need the wrinkles resolved: a grid close to the default
// spacing over the face (1.3 mm), on a narrower band of the head would be
// more work to set up than it saves; 192 x 160 takes ~20 ms to build.
SynthActorOptions DetailOptions(int seed = 1) {
  SynthActorOptions options;
  options.seed = seed;
  options.grid_u = 192;
  options.grid_v = 160;
  return options;
}

Eigen::VectorXd Activate(const FaceModel& model,
                         const std::vector<std::pair<std::string, double>>& units) {
  Eigen::VectorXd a = model.ZeroActivations();
  for (const auto& [name, level] : units) {
    const int k = model.FindUnit(name);
    EXPECT_GE(k, 0) << name;
    if (k >= 0) a[k] = level;
  }
  return a;
}

double MaxRowNorm(const MatX3d& X) { return X.rowwise().norm().maxCoeff(); }

// High-pass of a per-vertex field: the field minus `iterations` rounds of
// averaging over mesh neighbours (a low-pass of radius ~ sqrt(iterations)
// edges), projected on the neutral normal.
Eigen::VectorXd HighPassAlongNormal(const TriMesh& mesh, const MatX3d& field,
                                    int iterations) {
  std::vector<std::vector<int>> neighbours(mesh.NumVertices());
  for (int f = 0; f < mesh.NumFaces(); ++f) {
    for (int i = 0; i < 3; ++i) {
      neighbours[mesh.F(f, i)].push_back(mesh.F(f, (i + 1) % 3));
      neighbours[mesh.F(f, (i + 1) % 3)].push_back(mesh.F(f, i));
    }
  }
  for (auto& n : neighbours) {
    std::sort(n.begin(), n.end());
    n.erase(std::unique(n.begin(), n.end()), n.end());
  }
  MatX3d smooth = field;
  for (int it = 0; it < iterations; ++it) {
    MatX3d next = smooth;
    for (int v = 0; v < mesh.NumVertices(); ++v) {
      if (neighbours[v].empty()) continue;
      Vec3 sum = Vec3::Zero();
      for (int n : neighbours[v]) sum += smooth.row(n).transpose();
      next.row(v) = (0.5 * smooth.row(v).transpose() +
                     0.5 * sum / static_cast<double>(neighbours[v].size()))
                        .transpose();
    }
    smooth = next;
  }
  const MatX3d normals = VertexNormals(mesh.V, mesh.F);
  return (field - smooth).cwiseProduct(normals).rowwise().sum();
}

TEST(FaceModelTest, HasAtLeast25NamedUnits) {
  const FaceModel model(SmallOptions());
  EXPECT_GE(model.NumUnits(), 25);
  std::set<std::string> names;
  int jaw_units = 0;
  for (const ActionUnit& unit : model.units()) {
    EXPECT_TRUE(names.insert(unit.name).second) << unit.name;
    EXPECT_FALSE(unit.tags.empty()) << unit.name;
    if (unit.drives_jaw) ++jaw_units;
  }
  EXPECT_GE(jaw_units, 4);
}

TEST(FaceModelTest, EveryUnitMovesThePlausibleAmount) {
  const FaceModel model(SmallOptions());
  for (int k = 0; k < model.NumUnits(); ++k) {
    Eigen::VectorXd a = model.ZeroActivations();
    a[k] = 1.0;
    const ActionUnit& unit = model.units()[k];
    // The soft-tissue part (before the jaw rotates it): a few mm to ~15 mm.
    const double soft = MaxRowNorm(model.EvaluateUnskinned(a) - model.neutral().V);
    EXPECT_LT(soft, 16.0) << unit.name;
    const JawPose pose = model.JawPoseOf(a);
    if (unit.drives_jaw) {
      EXPECT_FALSE(pose.IsZero()) << unit.name;
      EXPECT_GT(soft, 0.2) << unit.name;  // a little soft tissue
    } else {
      EXPECT_TRUE(pose.IsZero()) << unit.name;
      EXPECT_GT(soft, 2.0) << unit.name;
    }
  }
}

TEST(FaceModelTest, ZeroActivationIsTheNeutral) {
  const FaceModel model(SmallOptions());
  const MatX3d x = model.Evaluate(model.ZeroActivations());
  EXPECT_LT((x - model.neutral().V).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_TRUE(model.JawPoseOf(model.ZeroActivations()).IsZero());
}

TEST(FaceModelTest, ActivationsAreClampedToUnitRange) {
  const FaceModel model(SmallOptions());
  Eigen::VectorXd a = model.ZeroActivations(), b = a;
  a[3] = 1.7;
  a[5] = -0.4;
  b[3] = 1.0;
  EXPECT_EQ(model.Evaluate(a), model.Evaluate(b));
}

TEST(FaceModelTest, IndependentOfThreadCount) {
  const FaceModel model(SmallOptions(4));
  Eigen::VectorXd a = model.ZeroActivations();
  for (int k = 0; k < model.NumUnits(); ++k) a[k] = 0.1 + 0.8 * ((k * 37) % 11) / 10.0;
  const MatX3d many = model.Evaluate(a);
  ThreadLimit one(1);
  const FaceModel model_one(SmallOptions(4));
  EXPECT_EQ(model_one.Evaluate(a), many);
}

TEST(FaceModelTest, LeftAndRightUnitsMirror) {
  const FaceModel model(SmallOptions(9));
  const FaceMesh& face = model.face();
  // Vertex (i, j) mirrors to (grid_u - 1 - i, j).
  auto mirror = [&](int v) {
    const int i = v % face.grid_u, j = v / face.grid_u;
    return j * face.grid_u + (face.grid_u - 1 - i);
  };
  int pairs = 0;
  for (int k = 0; k < model.NumUnits(); ++k) {
    const std::string& name = model.units()[k].name;
    if (name.size() < 2 || name.substr(name.size() - 2) != "_L") continue;
    const int r = model.FindUnit(name.substr(0, name.size() - 2) + "_R");
    ASSERT_GE(r, 0) << name;
    ++pairs;
    Eigen::VectorXd a = model.ZeroActivations(), b = a;
    a[k] = 0.8;
    b[r] = 0.8;
    const MatX3d xl = model.Evaluate(a), xr = model.Evaluate(b);
    double worst = 0;
    for (int v = 0; v < model.NumVertices(); ++v) {
      Vec3 m = xr.row(mirror(v)).transpose();
      m.x() = -m.x();
      worst = std::max(worst, (m - xl.row(v).transpose()).norm());
    }
    // Not exact: the triangulation's diagonals (and so the normals that
    // detail follows) are not mirror images.
    EXPECT_LT(worst, 0.3) << name;
  }
  EXPECT_GE(pairs, 8);
}

class FaceModelSeedTest : public ::testing::TestWithParam<int> {};

TEST_P(FaceModelSeedTest, CombinationsAreNotTheSumOfTheirParts) {
  const FaceModel model(DetailOptions(GetParam()));
  const MatX3d& x0 = model.neutral().V;
  const std::vector<std::pair<std::string, std::string>> pairs = {
      {"AU12_lip_corner_puller_L", "AU06_cheek_raiser_L"},
      {"AU26_jaw_drop", "AU22_lip_funneler"},
      {"AU24_lip_pressor", "AU17_chin_raiser"},
      {"AU18_lip_puckerer", "AU22_lip_funneler"}};
  for (const auto& [a_name, b_name] : pairs) {
    const MatX3d xa = model.Evaluate(Activate(model, {{a_name, 1.0}}));
    const MatX3d xb = model.Evaluate(Activate(model, {{b_name, 1.0}}));
    const MatX3d xab = model.Evaluate(Activate(model, {{a_name, 1.0}, {b_name, 1.0}}));
    const double excess = MaxRowNorm(xab - (xa + xb - x0));
    EXPECT_GT(excess, 1.0) << a_name << " + " << b_name;
    RecordProperty(a_name + "+" + b_name + "_excess_mm", std::to_string(excess));
  }
  // Units far apart do add up (nothing couples them).
  const MatX3d xa = model.Evaluate(Activate(model, {{"AU04_brow_lowerer", 1.0}}));
  const MatX3d xb = model.Evaluate(Activate(model, {{"AU17_chin_raiser", 1.0}}));
  const MatX3d xab = model.Evaluate(
      Activate(model, {{"AU04_brow_lowerer", 1.0}, {"AU17_chin_raiser", 1.0}}));
  EXPECT_LT(MaxRowNorm(xab - (xa + xb - x0)), 1e-9);
}

TEST(FaceModelTest, InBetweensAreNotLinear) {
  const FaceModel model(SmallOptions(3));
  const MatX3d& x0 = model.neutral().V;
  for (const std::string unit :
       {"AU12_lip_corner_puller_L", "AU45_blink_R", "AU26_jaw_drop", "AU34_cheek_puff"}) {
    const MatX3d half = model.Evaluate(Activate(model, {{unit, 0.5}}));
    const MatX3d full = model.Evaluate(Activate(model, {{unit, 1.0}}));
    EXPECT_GT(MaxRowNorm(half - (x0 + 0.5 * (full - x0))), 0.5) << unit;
  }
}

TEST(FaceModelTest, WrinklesOnlyInExpressions) {
  for (int seed : {1, 6}) {
    const FaceModel model(DetailOptions(seed));
    const FaceMesh& face = model.face();
    const MatX3d& x0 = model.neutral().V;
    const double bt = face.proportions.brow_t;
    std::vector<int> forehead;
    for (int v = 0; v < model.NumVertices(); ++v) {
      if (std::abs(face.st(v, 0)) < 40 && face.st(v, 1) > bt + 14 &&
          face.st(v, 1) < bt + 48) {
        forehead.push_back(v);
      }
    }
    ASSERT_GT(forehead.size(), 200u);
    auto amplitude = [&](const MatX3d& field) {
      const Eigen::VectorXd hp = HighPassAlongNormal(face.mesh, field, 8);
      double lo = 1e9, hi = -1e9;
      for (int v : forehead) {
        lo = std::min(lo, hp[v]);
        hi = std::max(hi, hp[v]);
      }
      return 0.5 * (hi - lo);
    };
    // The neutral surface itself has no fine detail on the forehead (what
    // remains is the curvature of the brow ridge and frontal eminences)...
    const double neutral = amplitude(x0);
    EXPECT_LT(neutral, 0.2) << "seed " << seed;
    // ...the raised brows' displacement has wrinkles,
    const auto brows = Activate(model, {{"AU01_inner_brow_raiser_L", 1.0},
                                        {"AU01_inner_brow_raiser_R", 1.0},
                                        {"AU02_outer_brow_raiser_L", 1.0},
                                        {"AU02_outer_brow_raiser_R", 1.0}});
    const double raised = amplitude(model.Evaluate(brows) - x0);
    EXPECT_GT(raised, 0.8) << "seed " << seed;
    EXPECT_GT(raised, 5.0 * neutral) << "seed " << seed;
    // ...that grow faster than the activation (a^2 / smoothstep): at 30%
    // they are well under 30% of their full amplitude.
    const double slight = amplitude(model.Evaluate(0.3 * brows) - x0);
    EXPECT_LT(slight, 0.2 * raised) << "seed " << seed;
    // The smooth lift alone (brow lowerer, no forehead detail) has none.
    const double lowered = amplitude(
        model.Evaluate(Activate(model, {{"AU04_brow_lowerer", 1.0}})) - x0);
    EXPECT_LT(lowered, 0.15) << "seed " << seed;
    RecordProperty("neutral_mm", std::to_string(neutral));
    RecordProperty("brow_raise_mm", std::to_string(raised));
  }
}

TEST_P(FaceModelSeedTest, JawDropRotatesTheChinAboutThePivot) {
  const FaceModel model(SmallOptions(GetParam()));
  const JawRig& rig = model.jaw_rig();
  const Eigen::VectorXd a = Activate(model, {{"AU26_jaw_drop", 1.0}});
  const JawPose pose = model.JawPoseOf(a);
  EXPECT_GT(pose.open_deg, 20.0);
  EXPECT_LT(pose.open_deg, 32.0);
  const MatX3d x = model.Evaluate(a);
  const MatX3d& x0 = model.neutral().V;
  const Rigid3 t = rig.Transform(pose);
  int fully = 0;
  for (int v = 0; v < model.NumVertices(); ++v) {
    if (rig.weights[v] != 1.0) continue;
    ++fully;
    const Vec3 p0 = x0.row(v).transpose(), p = x.row(v).transpose();
    EXPECT_NEAR((p - rig.pivot).norm(), (p0 - rig.pivot).norm(), 1e-9);
    EXPECT_LT((p - t * p0).norm(), 1e-9);
  }
  EXPECT_GT(fully, 100);
  RecordProperty("open_deg", std::to_string(pose.open_deg));
  RecordProperty("fully_weighted_vertices", std::to_string(fully));
  // Vertices off the jaw do not rotate with it.
  for (int v = 0; v < model.NumVertices(); ++v) {
    if (rig.weights[v] == 0.0 && model.face().st(v, 1) > 0) {
      EXPECT_LT((x.row(v) - x0.row(v)).norm(), 1e-9);
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Seeds, FaceModelSeedTest, ::testing::Values(2, 5, 13));

TEST(FaceModelTest, SidewaysAndThrustPoses) {
  const FaceModel model(SmallOptions());
  const JawPose left = model.JawPoseOf(Activate(model, {{"AU30_jaw_sideways_L", 1.0}}));
  const JawPose right = model.JawPoseOf(Activate(model, {{"AU30_jaw_sideways_R", 1.0}}));
  const JawPose thrust = model.JawPoseOf(Activate(model, {{"AU29_jaw_thrust", 1.0}}));
  EXPECT_NEAR(left.lateral_deg, 8.0, 1e-12);
  EXPECT_NEAR(right.lateral_deg, -8.0, 1e-12);
  EXPECT_NEAR(thrust.protrude_mm, 5.0, 1e-12);
  EXPECT_EQ(thrust.open_deg, 0.0);
  // Opening saturates: drop + stretch opens less than the sum of each.
  const double drop = model.JawPoseOf(Activate(model, {{"AU26_jaw_drop", 1.0}})).open_deg;
  const double stretch =
      model.JawPoseOf(Activate(model, {{"AU27_mouth_stretch", 1.0}})).open_deg;
  const double both = model.JawPoseOf(
      Activate(model, {{"AU26_jaw_drop", 1.0}, {"AU27_mouth_stretch", 1.0}})).open_deg;
  EXPECT_LT(both, drop + stretch - 5.0);
  EXPECT_GT(both, std::max(drop, stretch));
}

TEST(FaceModelTest, SaturationIsSoftAndBounded) {
  EXPECT_EQ(FaceModel::Saturate(3.0), 3.0);
  double previous = 0;
  for (double length = 0.5; length < 200; length *= 1.3) {
    const double s = FaceModel::Saturate(length);
    EXPECT_GE(s, previous);
    EXPECT_LE(s, length);
    EXPECT_LT(s, FaceModel::kSaturationLimit);
    previous = s;
  }
}

TEST(FaceModelTest, DeterministicBySeed) {
  const FaceModel a(SmallOptions(3)), b(SmallOptions(3)), c(SmallOptions(4));
  Eigen::VectorXd act = a.ZeroActivations();
  act.setConstant(0.35);
  EXPECT_EQ(a.Evaluate(act), b.Evaluate(act));
  EXPECT_GT((a.Evaluate(act) - c.Evaluate(act)).cwiseAbs().maxCoeff(), 0.5);
}

// Random combinations of a linear model's units (out-of-range activations
// clamped) are the sums of their scaled extremes (`extreme`: the units'
// displacements at activation 1).
void ExpectCombinationsAreSums(const FaceModel& model, const std::vector<MatX3d>& extreme,
                               int seed) {
  const MatX3d& x0 = model.neutral().V;
  const int K = model.NumUnits();
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-0.2, 1.2);
  for (int trial = 0; trial < 5; ++trial) {
    Eigen::VectorXd a(K);
    for (int k = 0; k < K; ++k) a[k] = u(rng);
    MatX3d sum = MatX3d::Zero(x0.rows(), 3);
    for (int k = 0; k < K; ++k) sum += std::clamp(a[k], 0.0, 1.0) * extreme[k];
    EXPECT_LT(MaxRowNorm(model.Evaluate(a) - x0 - sum), 1e-9);
    EXPECT_LT(MaxRowNorm(model.EvaluateUnskinned(a) - x0 - sum), 1e-9);
  }
}

// The linear rig (docs/synthetic.md, "Linear rig"): each unit's extreme is
// the generator's, in-betweens lie on the line and any combination is the
// sum of its units' scaled extremes; no jaw rig, the jaw pose is zero.
TEST(FaceModelTest, LinearRigIsLinearInTheActivations) {
  for (int seed : {1, 2, 3}) {
    SynthActorOptions options = SmallOptions(seed);
    const FaceModel generator(options);
    options.rig = "linear";
    const FaceModel linear(options);
    EXPECT_TRUE(linear.linear());
    EXPECT_FALSE(linear.has_jaw_rig());
    EXPECT_TRUE(generator.has_jaw_rig());
    const MatX3d& x0 = linear.neutral().V;
    EXPECT_EQ(MaxRowNorm(linear.Evaluate(linear.ZeroActivations()) - x0), 0.0);
    const int K = linear.NumUnits();
    std::vector<MatX3d> extreme(K);
    double nonlinearity = 0.0;  // the generator's in-between off the line
    for (int k = 0; k < K; ++k) {
      Eigen::VectorXd a = linear.ZeroActivations();
      a[k] = 1.0;
      extreme[k] = linear.Evaluate(a) - x0;
      EXPECT_LT(MaxRowNorm(extreme[k] - (generator.Evaluate(a) - x0)), 1e-12)
          << linear.units()[k].name;
      EXPECT_GT(MaxRowNorm(extreme[k]), 0.1) << linear.units()[k].name;
      a[k] = 0.5;
      EXPECT_LT(MaxRowNorm(linear.Evaluate(a) - x0 - 0.5 * extreme[k]), 1e-12);
      EXPECT_TRUE(linear.JawPoseOf(a).IsZero());
      nonlinearity = std::max(
          nonlinearity,
          MaxRowNorm(generator.Evaluate(a) - x0 - 0.5 * extreme[k]));
    }
    // The test can fail: the generator is not linear.
    EXPECT_GT(nonlinearity, 0.1);
    ExpectCombinationsAreSums(linear, extreme, seed);
  }
}

// The broad rig (docs/synthetic.md, "Broad rig"): linear like the linear
// rig, with the generator's units in their order plus mouth_left/right, and
// each unit's extreme the linear rig's plus a broad region that moves far
// more of the face.
TEST(FaceModelTest, BroadRigIsLinearWithBroaderExtremes) {
  for (int seed : {4, 9, 17}) {
    SynthActorOptions options = SmallOptions(seed);
    options.rig = "linear";
    const FaceModel linear(options);
    options.rig = "broad";
    const FaceModel broad(options);
    EXPECT_TRUE(broad.linear());
    EXPECT_TRUE(broad.broad());
    EXPECT_FALSE(linear.broad());
    EXPECT_FALSE(broad.has_jaw_rig());
    ASSERT_EQ(broad.NumUnits(), linear.NumUnits() + 2);
    for (int k = 0; k < linear.NumUnits(); ++k) {
      EXPECT_EQ(broad.units()[k].name, linear.units()[k].name);
    }
    EXPECT_GE(broad.FindUnit("mouth_left"), linear.NumUnits());
    EXPECT_GE(broad.FindUnit("mouth_right"), linear.NumUnits());
    const MatX3d& x0 = broad.neutral().V;
    EXPECT_EQ(broad.neutral().V, linear.neutral().V);
    const int K = broad.NumUnits();
    std::vector<MatX3d> extreme(K);
    int broader = 0;
    for (int k = 0; k < K; ++k) {
      Eigen::VectorXd a = broad.ZeroActivations();
      a[k] = 1.0;
      extreme[k] = broad.Evaluate(a) - x0;
      a[k] = 0.5;
      EXPECT_LT(MaxRowNorm(broad.Evaluate(a) - x0 - 0.5 * extreme[k]), 1e-12);
      EXPECT_TRUE(broad.JawPoseOf(a).IsZero());
      // Vertices moved by more than 0.5 mm, here and on the linear rig.
      const auto moved = [](const MatX3d& d) {
        return (d.rowwise().norm().array() > 0.5).count();
      };
      long on_linear = 0;
      if (k < linear.NumUnits()) {
        Eigen::VectorXd b = linear.ZeroActivations();
        b[k] = 1.0;
        on_linear = moved(linear.Evaluate(b) - x0);
      }
      if (moved(extreme[k]) > 2 * on_linear) ++broader;
    }
    // Most units move at least twice the area they move on the linear rig.
    EXPECT_GE(broader, 3 * K / 4) << seed;
    ExpectCombinationsAreSums(broad, extreme, seed);
  }
}

}  // namespace
}  // namespace hmc
