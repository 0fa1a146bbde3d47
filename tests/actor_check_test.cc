// `hmc actor check` as a user runs it: the summary of a good package, a
// non-zero exit with a message naming the file for a bad one, and the
// warnings on a valid package that looks like an export mistake (head moved
// away from the origin, turned Z-up, units off by 10 or 1000, a misspelt
// tag), each on a copy of the fixture changed in that one way.
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <cmath>
#include <functional>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "core/actor.h"
#include "core/file_util.h"
#include "tests/cli_runner.h"

namespace hmc {
namespace {

namespace fs = std::filesystem;

fs::path FixtureDir() {
  const char* source = std::getenv("HMC_SOURCE_DIR");
  const fs::path root = source != nullptr ? fs::path(source) : fs::current_path();
  return root / "tests" / "fixtures" / "dcc_actor";
}

// `from` replaced by `to` in the package's `file`.
struct TextEdit {
  std::string file, from, to;
};

std::string Replace(std::string text, const std::string& from, const std::string& to) {
  const size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) text.replace(at, from.size(), to);
  return text;
}

Vec3 Same(const Vec3& v) { return v; }

class ActorCheck : public ::testing::Test {
 protected:
  void SetUp() override {
    scratch_ = fs::temp_directory_path() /
               fmt::format("hmc_actor_check_test_{}_{}", getpid(),
                           ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(scratch_);
  }
  void TearDown() override {
    std::error_code ignored;
    fs::remove_all(scratch_, ignored);
  }
  // A copy of the fixture with every OBJ vertex mapped by `map` (neutral
  // and shapes alike, in the files' units) and each of `edits` applied.
  fs::path Edited(const std::function<Vec3(const Vec3&)>& map,
                  const std::vector<TextEdit>& edits = {}) {
    const fs::path package = scratch_ / "pkg";
    fs::remove_all(package);
    fs::copy(FixtureDir(), package, fs::copy_options::recursive);
    for (const auto& entry : fs::recursive_directory_iterator(package)) {
      if (entry.path().extension() != ".obj") continue;
      std::stringstream in(ReadFile(entry.path()));
      std::string line, out;
      while (std::getline(in, line)) {
        if (line.rfind("v ", 0) == 0) {
          std::stringstream fields(line.substr(2));
          Vec3 v;
          fields >> v.x() >> v.y() >> v.z();
          const Vec3 w = map(v);
          line = fmt::format("v {:.6f} {:.6f} {:.6f}", w.x(), w.y(), w.z());
        }
        out += line + "\n";
      }
      WriteFileAtomic(entry.path(), out);
    }
    for (const TextEdit& edit : edits) {
      WriteFileAtomic(package / edit.file,
                      Replace(ReadFile(package / edit.file), edit.from, edit.to));
    }
    return package;
  }

  nlohmann::json Warnings(const fs::path& package) {
    const CliResult result =
        RunHmc(fmt::format("-q actor check '{}' --json", package.string()), scratch_);
    EXPECT_EQ(result.exit_code, 0) << result.err;  // warnings do not fail
    return nlohmann::json::parse(result.out).at("warnings");
  }

  fs::path scratch_;
};

std::string Message(const nlohmann::json& warning) {
  return warning.at("message").get<std::string>();
}

TEST_F(ActorCheck, JsonSummaryAgreesWithTheLoadedActor) {
  const CliResult result =
      RunHmc(fmt::format("-q actor check '{}' --json", FixtureDir().string()),
             scratch_);
  ASSERT_EQ(result.exit_code, 0) << result.err;
  // Exactly one JSON object on stdout.
  const nlohmann::json json = nlohmann::json::parse(result.out);
  ASSERT_TRUE(json.is_object());

  const Actor actor = LoadActor(FixtureDir());
  EXPECT_EQ(json.at("name"), actor.name);
  EXPECT_EQ(json.at("units"), "cm");
  EXPECT_EQ(json.at("vertices"), actor.NumVertices());
  EXPECT_EQ(json.at("faces"), actor.neutral.NumFaces());
  EXPECT_EQ(json.at("uvs"), actor.neutral.UV.rows());
  EXPECT_EQ(json.at("shapes"), actor.shapes.size());
  EXPECT_EQ(json.at("markers"), actor.markers.size());
  EXPECT_EQ(json.at("has_uvs"), true);
  EXPECT_EQ(json.at("has_jaw_rig"), true);
  int jaw_markers = 0;
  for (const Marker& marker : actor.markers) jaw_markers += marker.HasTag("jaw");
  EXPECT_EQ(json.at("marker_tags").at("jaw"), jaw_markers);
  const auto bbox = BoundingBox(actor.neutral.V);
  for (int i = 0; i < 3; ++i) {
    EXPECT_DOUBLE_EQ(json.at("bbox_mm").at("min").at(i).get<double>(), bbox(0, i));
    EXPECT_DOUBLE_EQ(json.at("bbox_mm").at("max").at(i).get<double>(), bbox(1, i));
  }
  EXPECT_EQ(json.at("content_hash"), fmt::format("{:016x}", actor.content_hash));
}

TEST_F(ActorCheck, TextSummaryNamesTheActor) {
  const CliResult result = RunHmc(
      fmt::format("-q actor check '{}'", FixtureDir().string()), scratch_);
  ASSERT_EQ(result.exit_code, 0) << result.err;
  EXPECT_NE(result.out.find("dcc_actor"), std::string::npos) << result.out;
  EXPECT_NE(result.out.find("21 vertices"), std::string::npos) << result.out;
}

TEST_F(ActorCheck, BadPackageExitsNonZeroNamingTheFile) {
  const fs::path package = scratch_ / "pkg";
  fs::copy(FixtureDir(), package, fs::copy_options::recursive);
  std::string markers = ReadFile(package / "markers.csv");
  markers.replace(markers.find("brow_r,20,"), 10, "brow_r,99,");
  WriteFileAtomic(package / "markers.csv", markers);
  const CliResult result = RunHmc(
      fmt::format("-q actor check '{}' --json", package.string()), scratch_);
  EXPECT_EQ(result.exit_code, 2);
  EXPECT_NE(result.err.find("markers.csv:4:"), std::string::npos) << result.err;
  EXPECT_EQ(result.out, "");  // No JSON for a bad package.
}

TEST_F(ActorCheck, MissingFolderExitsNonZero) {
  const CliResult result = RunHmc(
      fmt::format("-q actor check '{}'", (scratch_ / "absent").string()), scratch_);
  EXPECT_EQ(result.exit_code, 2);
  EXPECT_NE(result.err.find("absent"), std::string::npos) << result.err;
}

TEST_F(ActorCheck, PlausibleFixtureHasNoWarnings) {
  const nlohmann::json warnings = Warnings(FixtureDir());
  EXPECT_TRUE(warnings.empty()) << warnings.dump();
}

TEST_F(ActorCheck, WarnsOnAHeadFarFromTheOrigin) {
  // Where a standing character's head is (cm): 160 cm up, 0 and 30 cm off.
  for (const Vec3& offset : {Vec3(0, 160, 0), Vec3(30, 0, 0), Vec3(0, 0, -20)}) {
    const nlohmann::json warnings =
        Warnings(Edited([&](const Vec3& v) -> Vec3 { return v + offset; }));
    ASSERT_EQ(warnings.size(), 1u) << warnings.dump();
    EXPECT_EQ(warnings[0].at("kind"), "origin");
  }
  // 5 cm off is still near.
  EXPECT_TRUE(Warnings(Edited([](const Vec3& v) -> Vec3 { return v + Vec3(0, 5, 0); })).empty());
}

TEST_F(ActorCheck, WarnsOnAHeadThatIsNotYUp) {
  // A Z-up export: head-space y became +z, z became -y.
  const nlohmann::json z_up =
      Warnings(Edited([](const Vec3& v) -> Vec3 { return Vec3(v.x(), -v.z(), v.y()); }));
  ASSERT_EQ(z_up.size(), 1u) << z_up.dump();
  EXPECT_EQ(z_up[0].at("kind"), "orientation");
  EXPECT_NE(Message(z_up[0]).find("+z"), std::string::npos) << z_up.dump();
  // Upside down.
  const nlohmann::json down =
      Warnings(Edited([](const Vec3& v) -> Vec3 { return Vec3(-v.x(), -v.y(), v.z()); }));
  ASSERT_EQ(down.size(), 1u) << down.dump();
  EXPECT_NE(Message(down[0]).find("-y"), std::string::npos) << down.dump();
  // Facing sideways (+x) but upright: the face's normals tell.
  const nlohmann::json side =
      Warnings(Edited([](const Vec3& v) -> Vec3 { return Vec3(v.z(), v.y(), -v.x()); }));
  ASSERT_EQ(side.size(), 1u) << side.dump();
  EXPECT_EQ(side[0].at("kind"), "orientation");
  EXPECT_NE(Message(side[0]).find("+x"), std::string::npos) << side.dump();
}

TEST_F(ActorCheck, WarnsOnUnitsThatLookLikeCentimetresOrMetres) {
  // The fixture's numbers are centimetres: read as mm the head is 8 mm.
  const nlohmann::json cm = Warnings(Edited(Same, {{"actor.yaml", "units: cm", "units: mm"}}));
  ASSERT_EQ(cm.size(), 1u) << cm.dump();
  EXPECT_EQ(cm[0].at("kind"), "units");
  EXPECT_NE(Message(cm[0]).find("units: cm"), std::string::npos) << cm.dump();
  // Metres, read as cm.
  const nlohmann::json m = Warnings(Edited([](const Vec3& v) -> Vec3 { return 0.01 * v; }));
  ASSERT_EQ(m.size(), 1u) << m.dump();
  EXPECT_EQ(m[0].at("kind"), "units");
  EXPECT_NE(Message(m[0]).find("metres"), std::string::npos) << m.dump();
  // Millimetres declared cm: a head 10 times too big (and so far from the
  // origin too).
  const nlohmann::json mm = Warnings(Edited([](const Vec3& v) -> Vec3 { return 10.0 * v; }));
  int units = 0;
  for (const auto& w : mm) {
    if (w.at("kind") != "units") continue;
    ++units;
    EXPECT_NE(Message(w).find("units: mm"), std::string::npos) << mm.dump();
  }
  EXPECT_EQ(units, 1) << mm.dump();
}

TEST_F(ActorCheck, WarnsOnUnknownTagsNamingTheMarkerAndTheNearestKnownTag) {
  const nlohmann::json stabel = Warnings(
      Edited(Same, {{"markers.csv", "nose_bridge,2,,,stable", "nose_bridge,2,,,stabel"}}));
  ASSERT_EQ(stabel.size(), 1u) << stabel.dump();
  EXPECT_EQ(stabel[0].at("kind"), "tag");
  for (const char* part : {"nose_bridge", "'stabel'", "'stable'"}) {
    EXPECT_NE(Message(stabel[0]).find(part), std::string::npos) << part << ": " << stabel.dump();
  }
  // A region tag of the package's own is known once a shape carries it.
  const TextEdit lips = {"markers.csv", "mouth_c,,9,0.25 0.25 0.25 0.25,mouth jaw",
                         "mouth_c,,9,0.25 0.25 0.25 0.25,mouth jaw lips"};
  const nlohmann::json alone = Warnings(Edited(Same, {lips}));
  ASSERT_EQ(alone.size(), 1u) << alone.dump();
  EXPECT_NE(Message(alone[0]).find("'lips'"), std::string::npos) << alone.dump();
  EXPECT_TRUE(Warnings(Edited(Same, {lips, {"actor.yaml", "tags: [mouth, jaw]",
                                            "tags: [mouth, jaw, lips]"}}))
                  .empty());
}

// An actor without a jaw rig whose dataset has jaw shapes (the synthetic
// linear rig: its jaw units are built with the generator's rig, which the
// generator actor of the same seed carries): `hmc actor check` reports the
// rig estimated from them, `--write_jaw_rig` writes a package that loads
// with it, and an actor that has a rig is refused.
TEST_F(ActorCheck, EstimatesAJawRigFromTheDatasetsJawShapes) {
  for (int seed : {3, 4}) {
    const std::string common = fmt::format(
        "-q actor synth --grid_u 24 --grid_v 20 --dataset_inbetweens false "
        "--dataset_combos false --seed {}",
        seed);
    const fs::path linear = scratch_ / fmt::format("linear{}", seed);
    const fs::path generator = scratch_ / fmt::format("generator{}", seed);
    ASSERT_EQ(RunHmc(fmt::format("{} --rig linear --out '{}'", common, linear.string()), scratch_)
                  .exit_code, 0);
    ASSERT_EQ(RunHmc(fmt::format("{} --rig generator --out '{}'", common, generator.string()),
                     scratch_)
                  .exit_code, 0);
    const Actor truth_actor = LoadActor(generator);
    ASSERT_TRUE(truth_actor.jaw_rig.has_value());
    const JawRig& truth = *truth_actor.jaw_rig;

    const CliResult check =
        RunHmc(fmt::format("-q actor check '{}' --json", linear.string()), scratch_);
    ASSERT_EQ(check.exit_code, 0) << check.err;
    const nlohmann::json json = nlohmann::json::parse(check.out);
    EXPECT_EQ(json.at("has_jaw_rig"), false);
    const nlohmann::json& estimate = json.at("jaw_rig_estimate");
    ASSERT_TRUE(estimate.is_object()) << json.dump();
    EXPECT_NE(estimate.at("from_shapes").at("open").get<std::string>().find("jaw"),
              std::string::npos);
    Vec3 hinge, pivot;
    for (int i = 0; i < 3; ++i) {
      hinge[i] = estimate.at("hinge").at(i).get<double>();
      pivot[i] = estimate.at("pivot_mm").at(i).get<double>();
    }
    EXPECT_GT(hinge.dot(truth.axes.col(0)), std::cos(0.5 * M_PI / 180)) << hinge.transpose();
    const Vec3 offset = truth.pivot - pivot;
    EXPECT_LT((offset - offset.dot(hinge) * hinge).norm(), 0.5) << pivot.transpose();

    const fs::path written = scratch_ / fmt::format("with_jaw{}", seed);
    const CliResult write = RunHmc(
        fmt::format("-q actor check '{}' --write_jaw_rig '{}'", linear.string(), written.string()),
        scratch_);
    ASSERT_EQ(write.exit_code, 0) << write.err;
    const Actor with_jaw = LoadActor(written);
    ASSERT_TRUE(with_jaw.jaw_rig.has_value());
    EXPECT_LT((with_jaw.jaw_rig->pivot - pivot).norm(), 1e-6);
    int posed = 0;
    for (const Shape& shape : with_jaw.shapes) posed += !shape.jaw.IsZero();
    EXPECT_EQ(posed, estimate.at("shapes_with_jaw_pose").get<int>());
    EXPECT_GT(posed, 0);

    const CliResult refused = RunHmc(
        fmt::format("-q actor check '{}' --write_jaw_rig '{}'", generator.string(),
                    (scratch_ / "refused").string()),
        scratch_);
    EXPECT_NE(refused.exit_code, 0);
    EXPECT_NE(refused.err.find("has a jaw rig already"), std::string::npos) << refused.err;
  }
}

}  // namespace
}  // namespace hmc
