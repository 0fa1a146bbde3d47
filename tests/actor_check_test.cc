// `hmc actor check` as a user runs it: the summary of a good package, and a
// non-zero exit with a message naming the file for a bad one.
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
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
  fs::path scratch_;
};

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

}  // namespace
}  // namespace hmc
