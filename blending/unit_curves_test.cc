#include "blending/unit_curves.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>

#include "indexing/lgi_test_actor.h"

namespace hmc {
namespace {

// The small test actor with its in-betweens named as the synthetic actor
// names them ("_050"), and one combination shape.
Actor UnitTestActor(int seed, bool jaw) {
  testing::LgiTestActorOptions o;
  o.seed = seed;
  o.jaw = jaw;
  Actor actor = testing::MakeLgiTestActor(o);
  for (Shape& s : actor.shapes) {
    if (s.name.size() > 3 && s.name.compare(s.name.size() - 3, 3, "_50") == 0) {
      s.name = s.name.substr(0, s.name.size() - 3) + "_050";
    }
  }
  Shape combo = actor.shapes[0];
  combo.name = "e0_100__e2_100";
  actor.shapes.push_back(combo);
  return actor;
}

std::string ReadText(const std::filesystem::path& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// The numbers of the bracketed list that follows `key` at or after `from`
// (parentheses and commas are separators).
std::vector<double> ListAfter(const std::string& text, const std::string& key, size_t* from) {
  const size_t at = text.find(key, *from);
  EXPECT_NE(at, std::string::npos) << key;
  if (at == std::string::npos) return {};
  // The list's '[' after the key (a key may itself end with one, and a
  // type's "[]" comes before it).
  const size_t open = text.find('[', at + key.size() - (key.back() == '[' ? 1 : 0));
  const size_t close = text.find(']', open);
  *from = close;
  std::string body = text.substr(open + 1, close - open - 1);
  for (char& c : body) {
    if (c == '(' || c == ')' || c == ',') c = ' ';
  }
  std::istringstream in(body);
  std::vector<double> out;
  for (double x; in >> x;) out.push_back(x);
  return out;
}

class UnitSeeds : public ::testing::TestWithParam<int> {};

// The units are the shapes that are not combinations, each at its highest
// activation; meshes made by the rig from weights in [0, 1] and jaw poses
// are fitted back to those weights, and reproduced.
TEST_P(UnitSeeds, TheRigsOwnMeshesAreFittedExactly) {
  for (bool jaw : {false, true}) {
    const Actor actor = UnitTestActor(GetParam(), jaw);
    const UnitRig rig = UnitRigFromActor(actor);
    ASSERT_EQ(rig.names.size(), 6u);
    for (size_t u = 0; u < rig.names.size(); ++u) {
      EXPECT_EQ(rig.names[u], "e" + std::to_string(u));
      EXPECT_EQ(actor.shapes[rig.shape[u]].name, rig.names[u] + "_100");
    }
    // A unit's own shape, skinned by its own jaw pose, is the rig at
    // weight 1.
    Eigen::VectorXd one = Eigen::VectorXd::Zero(6);
    one[1] = 1.0;
    const Shape& s1 = actor.shapes[rig.shape[1]];
    EXPECT_LT((EvaluateUnitRig(rig, actor, one, s1.jaw) - (actor.neutral.V + s1.displacement))
                  .cwiseAbs()
                  .maxCoeff(),
              1e-9);
    std::mt19937 rng(70 + GetParam());
    std::uniform_real_distribution<double> uni(0.0, 1.0);
    std::vector<Eigen::VectorXd> truth;
    std::vector<MatX3d> meshes;
    std::vector<JawPose> poses;
    for (int f = 0; f < 6; ++f) {
      Eigen::VectorXd w(6);
      for (int u = 0; u < 6; ++u) w[u] = uni(rng) < 0.3 ? 0.0 : uni(rng);
      JawPose pose;
      if (jaw) pose.open_deg = 12 * uni(rng);
      truth.push_back(w);
      poses.push_back(pose);
      meshes.push_back(EvaluateUnitRig(rig, actor, w, pose));
    }
    const UnitFit fit = FitUnitWeights(rig, actor, meshes, poses);
    for (int f = 0; f < 6; ++f) {
      EXPECT_LT((fit.weights[f] - truth[f]).cwiseAbs().maxCoeff(), 1e-6) << "frame " << f;
      EXPECT_LT(fit.mean_mm[f], 1e-6);
    }
    EXPECT_LT(fit.mean_mm_all, 1e-6);
  }
}

// A mesh beyond the units' span: the fit's reported error is the rig's
// distance from it, and larger than the bounded weights' exact fit.
TEST_P(UnitSeeds, TheFitReportsWhatItMisses) {
  const Actor actor = UnitTestActor(GetParam(), /*jaw=*/false);
  const UnitRig rig = UnitRigFromActor(actor);
  MatX3d x = actor.neutral.V + 0.5 * rig.displacement[0];
  for (int v = 0; v < x.rows(); ++v) x(v, 2) += std::exp(-x.row(v).head<2>().squaredNorm() / 200.0);
  const UnitFit fit = FitUnitWeights(rig, actor, {x}, {});
  const double measured =
      (EvaluateUnitRig(rig, actor, fit.weights[0], JawPose()) - x).rowwise().norm().mean();
  EXPECT_NEAR(fit.mean_mm[0], measured, 1e-12);
  EXPECT_GT(fit.mean_mm[0], 1e-3);
  for (int u = 0; u < fit.weights[0].size(); ++u) {
    EXPECT_GE(fit.weights[0][u], 0.0);
    EXPECT_LE(fit.weights[0][u], 1.0);
  }
}

// The files: weights.csv and curves.csv hold the channels' values; the
// .usda, evaluated as UsdSkel evaluates it (blend shapes, then linear blend
// skinning by the joints' weights), gives the rig's mesh at every frame
// within float precision.
TEST_P(UnitSeeds, TheWrittenUsdReproducesTheRig) {
  const Actor actor = UnitTestActor(GetParam(), /*jaw=*/true);
  const UnitRig rig = UnitRigFromActor(actor);
  std::mt19937 rng(90 + GetParam());
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  std::vector<MatX3d> meshes;
  std::vector<JawPose> poses;
  for (int f = 0; f < 3; ++f) {
    Eigen::VectorXd w(6);
    for (int u = 0; u < 6; ++u) w[u] = uni(rng);
    JawPose pose;
    pose.open_deg = 15 * uni(rng);
    pose.lateral_deg = 2 * uni(rng) - 1;
    pose.protrude_mm = uni(rng);
    poses.push_back(pose);
    meshes.push_back(EvaluateUnitRig(rig, actor, w, pose));
  }
  const UnitFit fit = FitUnitWeights(rig, actor, meshes, poses);
  const UnitAnimation animation = MakeUnitAnimation(rig, actor, fit, poses, 11, 24.0);
  ASSERT_EQ(animation.channels.size(), 9u);
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("hmc_unit_curves_" + std::to_string(GetParam()));
  std::filesystem::create_directories(dir);
  WriteUnitWeightsCsv(dir / "weights.csv", animation);
  WriteUnitCurvesCsv(dir / "curves.csv", animation);
  WriteUnitRigUsda(dir / "rig.usda", rig, actor, animation, poses);

  const std::string csv = ReadText(dir / "weights.csv");
  EXPECT_EQ(csv.substr(0, csv.find('\n')),
            "frame,e0,e1,e2,e3,e4,e5,jaw_open_deg,jaw_lateral_deg,jaw_protrude_mm");
  std::istringstream rows(csv);
  std::string line;
  std::getline(rows, line);
  for (int f = 0; f < 3; ++f) {
    std::getline(rows, line);
    for (char& c : line) c = c == ',' ? ' ' : c;
    std::istringstream in(line);
    int frame = 0;
    in >> frame;
    EXPECT_EQ(frame, 11 + f);
    for (size_t c = 0; c < animation.channels.size(); ++c) {
      double v = 0;
      in >> v;
      EXPECT_NEAR(v, animation.values[f][c], 1e-8 * std::max(1.0, std::abs(v)));
    }
  }
  const std::string curves = ReadText(dir / "curves.csv");
  EXPECT_EQ(std::count(curves.begin(), curves.end(), '\n'), 1 + 9 * 3);

  const std::string usd = ReadText(dir / "rig.usda");
  size_t at = usd.find("def SkelAnimation");
  std::vector<std::vector<double>> weights, translations, rotations;
  for (int f = 0; f < 3; ++f) weights.push_back(ListAfter(usd, std::to_string(11 + f) + ": [", &at));
  for (int f = 0; f < 3; ++f) translations.push_back(ListAfter(usd, std::to_string(11 + f) + ": [", &at));
  for (int f = 0; f < 3; ++f) rotations.push_back(ListAfter(usd, std::to_string(11 + f) + ": [", &at));
  at = usd.find("def Mesh");
  const std::vector<double> points = ListAfter(usd, "point3f[] points", &at);
  const std::vector<double> joint_weights = ListAfter(usd, "primvars:skel:jointWeights", &at);
  ASSERT_EQ(static_cast<int>(points.size()), 3 * actor.NumVertices());
  std::vector<std::vector<double>> offsets, indices;
  for (int u = 0; u < 6; ++u) {
    offsets.push_back(ListAfter(usd, "offsets", &at));
    indices.push_back(ListAfter(usd, "pointIndices", &at));
    ASSERT_EQ(offsets[u].size(), 3 * indices[u].size());
  }
  for (int f = 0; f < 3; ++f) {
    ASSERT_EQ(weights[f].size(), 6u);
    ASSERT_EQ(translations[f].size(), 6u);  // root, jaw
    ASSERT_EQ(rotations[f].size(), 8u);
    Rigid3 jaw = Rigid3::Identity();
    jaw.linear() = Eigen::Quaterniond(rotations[f][4], rotations[f][5], rotations[f][6],
                                      rotations[f][7])
                       .normalized()
                       .toRotationMatrix();
    jaw.translation() = Vec3(translations[f][3], translations[f][4], translations[f][5]);
    MatX3d x(actor.NumVertices(), 3);
    for (int v = 0; v < actor.NumVertices(); ++v) {
      x.row(v) << points[3 * v], points[3 * v + 1], points[3 * v + 2];
    }
    for (int u = 0; u < 6; ++u) {
      for (size_t i = 0; i < indices[u].size(); ++i) {
        const int v = static_cast<int>(indices[u][i]);
        for (int c = 0; c < 3; ++c) x(v, c) += weights[f][u] * offsets[u][3 * i + c];
      }
    }
    double worst = 0;
    for (int v = 0; v < actor.NumVertices(); ++v) {
      const Vec3 p = x.row(v).transpose();
      const Vec3 skinned = joint_weights[2 * v] * p + joint_weights[2 * v + 1] * (jaw * p);
      worst = std::max(worst, (skinned - meshes[f].row(v).transpose()).norm());
    }
    EXPECT_LT(worst, 1e-3) << "frame " << f;
  }
  std::filesystem::remove_all(dir);
}

INSTANTIATE_TEST_SUITE_P(Seeds, UnitSeeds, ::testing::Values(1, 2, 3));

}  // namespace
}  // namespace hmc
