// `hmc actor check` as a user runs it: the summary of a good package, a
// non-zero exit with a message naming the file for a bad one, and the
// warnings on a valid package that looks like an export mistake (head moved
// away from the origin, turned Z-up, units off by 10 or 1000, a misspelt
// tag), each on a copy of the fixture changed in that one way.
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <functional>
#include <sstream>
#include <filesystem>
#include <string>

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
  // and shapes alike, in the files' units) and `edit` applied to the text
  // of the named files.
  fs::path Edited(const std::function<Vec3(const Vec3&)>& map,
                  const std::vector<std::pair<std::string, std::function<std::string(std::string)>>>&
                      edits = {}) {
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
    for (const auto& [file, edit] : edits) {
      WriteFileAtomic(package / file, edit(ReadFile(package / file)));
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

std::string Replace(std::string text, const std::string& from, const std::string& to) {
  const size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) text.replace(at, from.size(), to);
  return text;
}

std::string KindsOf(const nlohmann::json& warnings) {
  std::string kinds;
  for (const auto& w : warnings) kinds += w.at("kind").get<std::string>() + " ";
  return kinds;
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
    const nlohmann::json warnings = Warnings(Edited([&](const Vec3& v) -> Vec3 { return v + offset; }));
    ASSERT_EQ(warnings.size(), 1u) << warnings.dump();
    EXPECT_EQ(warnings[0].at("kind"), "origin");
  }
  // 5 cm off is still near.
  EXPECT_TRUE(Warnings(Edited([](const Vec3& v) -> Vec3 { return v + Vec3(0, 5, 0); })).empty());
}

TEST_F(ActorCheck, WarnsOnAHeadThatIsNotYUp) {
  // A Z-up export: head-space y became +z, z became -y.
  const nlohmann::json z_up = Warnings(Edited([](const Vec3& v) -> Vec3 { return Vec3(v.x(), -v.z(), v.y()); }));
  ASSERT_EQ(z_up.size(), 1u) << z_up.dump();
  EXPECT_EQ(z_up[0].at("kind"), "orientation");
  EXPECT_NE(z_up[0].at("message").get<std::string>().find("+z"), std::string::npos) << z_up.dump();
  // Upside down.
  const nlohmann::json down = Warnings(Edited([](const Vec3& v) -> Vec3 { return Vec3(-v.x(), -v.y(), v.z()); }));
  ASSERT_EQ(down.size(), 1u) << down.dump();
  EXPECT_NE(down[0].at("message").get<std::string>().find("-y"), std::string::npos) << down.dump();
  // Facing sideways (+x) but upright: the face's normals tell.
  const nlohmann::json side = Warnings(Edited([](const Vec3& v) -> Vec3 { return Vec3(v.z(), v.y(), -v.x()); }));
  ASSERT_EQ(side.size(), 1u) << side.dump();
  EXPECT_EQ(side[0].at("kind"), "orientation");
  EXPECT_NE(side[0].at("message").get<std::string>().find("+x"), std::string::npos) << side.dump();
}

TEST_F(ActorCheck, WarnsOnUnitsThatLookLikeCentimetresOrMetres) {
  const auto units = [](const std::string& unit) {
    return std::make_pair(std::string("actor.yaml"), std::function<std::string(std::string)>(
        [unit](std::string text) { return Replace(text, "units: cm", "units: " + unit); }));
  };
  const auto keep = [](const Vec3& v) -> Vec3 { return v; };
  // The fixture's numbers are centimetres: read as mm the head is 8 mm.
  const nlohmann::json cm = Warnings(Edited(keep, {units("mm")}));
  ASSERT_EQ(cm.size(), 1u) << cm.dump();
  EXPECT_EQ(cm[0].at("kind"), "units");
  EXPECT_NE(cm[0].at("message").get<std::string>().find("units: cm"), std::string::npos) << cm.dump();
  // Metres, read as cm.
  const nlohmann::json m = Warnings(Edited([](const Vec3& v) -> Vec3 { return 0.01 * v; }));
  ASSERT_EQ(m.size(), 1u) << m.dump();
  EXPECT_EQ(m[0].at("kind"), "units");
  EXPECT_NE(m[0].at("message").get<std::string>().find("metres"), std::string::npos) << m.dump();
  // Millimetres declared cm: a head 10 times too big (and so far from the
  // origin too).
  const nlohmann::json mm = Warnings(Edited([](const Vec3& v) -> Vec3 { return 10.0 * v; }));
  EXPECT_NE(KindsOf(mm).find("units"), std::string::npos) << mm.dump();
  for (const auto& w : mm) {
    if (w.at("kind") == "units") {
      EXPECT_NE(w.at("message").get<std::string>().find("units: mm"), std::string::npos);
    }
  }
}

TEST_F(ActorCheck, WarnsOnUnknownTagsNamingTheMarkerAndTheNearestKnownTag) {
  const auto keep = [](const Vec3& v) -> Vec3 { return v; };
  const auto markers = [](const std::string& from, const std::string& to) {
    return std::make_pair(std::string("markers.csv"), std::function<std::string(std::string)>(
        [from, to](std::string text) { return Replace(text, from, to); }));
  };
  const nlohmann::json stabel = Warnings(Edited(keep, {markers("nose_bridge,2,,,stable", "nose_bridge,2,,,stabel")}));
  ASSERT_EQ(stabel.size(), 1u) << stabel.dump();
  EXPECT_EQ(stabel[0].at("kind"), "tag");
  const std::string message = stabel[0].at("message").get<std::string>();
  for (const char* part : {"nose_bridge", "'stabel'", "'stable'"}) {
    EXPECT_NE(message.find(part), std::string::npos) << part << ": " << message;
  }
  // A region tag of the package's own is known once a shape carries it.
  const auto lips = markers("mouth_c,,9,0.25 0.25 0.25 0.25,mouth jaw",
                            "mouth_c,,9,0.25 0.25 0.25 0.25,mouth jaw lips");
  const nlohmann::json alone = Warnings(Edited(keep, {lips}));
  ASSERT_EQ(alone.size(), 1u) << alone.dump();
  EXPECT_NE(alone[0].at("message").get<std::string>().find("'lips'"), std::string::npos);
  const auto shape_tag = std::make_pair(std::string("actor.yaml"), std::function<std::string(std::string)>(
      [](std::string text) { return Replace(text, "tags: [mouth, jaw]", "tags: [mouth, jaw, lips]"); }));
  EXPECT_TRUE(Warnings(Edited(keep, {lips, shape_tag})).empty());
}

}  // namespace
}  // namespace hmc
