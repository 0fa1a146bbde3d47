// `hmc actor synth --holdout` and `hmc actor frames` as a user runs them on a
// small synthetic actor of each rig (generator, linear, broad): the held-out
// package records its units, passes `hmc actor check` without a warning and
// indexes; every kind of frames runs; heldout frames activate only those units;
// --noise-mm gives bundles whose difference from the noise-free bundles has
// the requested std; heldout/mixed frames of an actor without held-out units
// are refused with a message naming synth.yaml.
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "core/actor.h"
#include "core/file_util.h"
#include "core/frame_data.h"
#include "synth/synth_actor.h"
#include "tests/cli_runner.h"

namespace hmc {
namespace {

namespace fs = std::filesystem;

class ActorFramesCli : public ::testing::Test {
 protected:
  void SetUp() override {
    scratch_ = fs::temp_directory_path() /
               fmt::format("hmc_actor_frames_test_{}_{}", getpid(),
                           ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(scratch_);
    fs::create_directories(scratch_);
  }
  void TearDown() override {
    std::error_code ignored;
    fs::remove_all(scratch_, ignored);
  }

  // A small package (40 x 32 grid, no combinations: quick to index).
  fs::path Synth(const std::string& name, int seed, int holdout,
                 const std::string& rig = "generator") {
    const fs::path dir = scratch_ / name;
    const CliResult result = RunHmc(
        fmt::format("-q actor synth --out '{}' --seed {} --grid_u 40 --grid_v 32 "
                    "--dataset_combos false --holdout {} --rig {}",
                    dir.string(), seed, holdout, rig),
        scratch_);
    EXPECT_EQ(result.exit_code, 0) << result.err;
    return dir;
  }

  fs::path scratch_;
};

std::vector<std::string> SplitCsvLine(const std::string& line) {
  std::vector<std::string> cells;
  std::stringstream stream(line);
  std::string cell;
  while (std::getline(stream, cell, ',')) cells.push_back(cell);
  return cells;
}

class ActorFramesRigCli : public ActorFramesCli,
                          public ::testing::WithParamInterface<const char*> {};

TEST_P(ActorFramesRigCli, HoldoutPackageChecksIndexesAndGivesHeldOutFrames) {
  const fs::path actor_dir = Synth("actor", 3, 2, GetParam());
  const SynthActorOptions synth = ReadSynthActorOptions(actor_dir);
  EXPECT_EQ(synth.holdout, 2);
  std::set<std::string> held;
  {
    std::stringstream names(synth.holdout_units);
    std::string name;
    while (std::getline(names, name, ',')) held.insert(name);
  }
  ASSERT_EQ(held.size(), 2u) << synth.holdout_units;

  // No shape of the package is built from a held-out unit.
  const Actor actor = LoadActor(actor_dir);
  for (const Shape& shape : actor.shapes) {
    for (const std::string& unit : held) {
      EXPECT_NE(shape.name.rfind(unit, 0), 0u) << shape.name;
    }
  }
  const CliResult check =
      RunHmc(fmt::format("-q actor check '{}' --json", actor_dir.string()), scratch_);
  ASSERT_EQ(check.exit_code, 0) << check.err;
  const nlohmann::json summary = nlohmann::json::parse(check.out);
  EXPECT_EQ(summary.at("shapes"), actor.shapes.size());
  // The generator's packages are what a studio should write: no warning.
  EXPECT_TRUE(summary.at("warnings").empty()) << summary.at("warnings").dump();
  const CliResult index =
      RunHmc(fmt::format("-q index --actor '{}'", actor_dir.string()), scratch_);
  EXPECT_EQ(index.exit_code, 0) << index.err;

  // heldout frames, noise-free and noisy from the same seed.
  const fs::path exact_dir = scratch_ / "exact", noisy_dir = scratch_ / "noisy";
  for (const auto& [dir, flag] :
       {std::make_pair(exact_dir, std::string()),
        std::make_pair(noisy_dir, std::string("--noise-mm 0.5"))}) {
    const CliResult frames = RunHmc(
        fmt::format("-q actor frames --actor '{}' --out '{}' --kind heldout "
                    "--frames 12 --seed 5 {}",
                    actor_dir.string(), dir.string(), flag),
        scratch_);
    ASSERT_EQ(frames.exit_code, 0) << frames.err;
  }
  // activations.csv: only held-out columns are ever non-zero.
  std::stringstream activations(ReadFile(noisy_dir / "activations.csv"));
  std::string line;
  std::getline(activations, line);
  const std::vector<std::string> header = SplitCsvLine(line);
  int rows = 0;
  while (std::getline(activations, line)) {
    const std::vector<std::string> cells = SplitCsvLine(line);
    ASSERT_EQ(cells.size(), header.size());
    int active = 0;
    for (size_t c = 1; c < cells.size(); ++c) {
      if (std::stod(cells[c]) == 0) continue;
      EXPECT_TRUE(held.count(header[c])) << header[c];
      ++active;
    }
    EXPECT_GE(active, 1);
    ++rows;
  }
  EXPECT_EQ(rows, 12);

  // Noise std measured on bundles.csv: within 5 standard errors of 0.5 mm.
  const std::vector<BundleFrame> exact = ReadBundlesCsv(exact_dir / "bundles.csv");
  const std::vector<BundleFrame> noisy = ReadBundlesCsv(noisy_dir / "bundles.csv");
  ASSERT_EQ(exact.size(), noisy.size());
  double sum_sq = 0;
  int n = 0;
  for (size_t f = 0; f < exact.size(); ++f) {
    ASSERT_EQ(exact[f].bundles.size(), actor.markers.size());
    for (const auto& [name, p] : exact[f].bundles) {
      sum_sq += (noisy[f].bundles.at(name) - p).squaredNorm();
      n += 3;
    }
  }
  EXPECT_NEAR(std::sqrt(sum_sq / n), 0.5, 5 * 0.5 / std::sqrt(2.0 * n));

  // Every other kind runs on the package too.
  for (const std::string kind : {"dataset", "combos", "performance", "mixed"}) {
    const CliResult frames = RunHmc(
        fmt::format("-q actor frames --actor '{}' --out '{}' --kind {} --frames 6 --seed 2",
                    actor_dir.string(), (scratch_ / kind).string(), kind),
        scratch_);
    EXPECT_EQ(frames.exit_code, 0) << kind << ": " << frames.err;
    EXPECT_TRUE(fs::exists(scratch_ / kind / "bundles.csv")) << kind;
  }
}

INSTANTIATE_TEST_SUITE_P(Rigs, ActorFramesRigCli,
                         ::testing::Values("generator", "linear", "broad"));

TEST_F(ActorFramesCli, HeldOutKindsRefuseAnActorWithoutHeldOutUnits) {
  const fs::path actor_dir = Synth("plain", 1, 0);
  for (const std::string kind : {"heldout", "mixed"}) {
    const CliResult result = RunHmc(
        fmt::format("-q actor frames --actor '{}' --out '{}' --kind {}",
                    actor_dir.string(), (scratch_ / kind).string(), kind),
        scratch_);
    EXPECT_EQ(result.exit_code, 2) << kind;
    EXPECT_NE(result.err.find("synth.yaml"), std::string::npos) << result.err;
    EXPECT_NE(result.err.find("held-out"), std::string::npos) << result.err;
    // Nothing written for a refused command.
    EXPECT_FALSE(fs::exists(scratch_ / kind / "bundles.csv"));
  }
}

}  // namespace
}  // namespace hmc
