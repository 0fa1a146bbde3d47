// The shared fixture of the hmc batch tests (tests/batch_test.cc,
// tests/batch_slurm_test.cc): a small actor and three short synthetic takes
// of different seeds, made once per test binary.
#pragma once

#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "core/file_util.h"
#include "tests/cli_runner.h"
#include "tests/small_actor.h"

namespace hmc {

namespace fs = std::filesystem;

constexpr int kFrames = 3;

class BatchTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new fs::path(FreshTestDir("hmc_batch_test", 49));
    const fs::path& d = *dir_;
    ASSERT_EQ(SynthTestActor(d / "actor", d).exit_code, 0);
    // Three takes of different seeds.
    for (int seed : {1, 2, 3}) {
      const CliResult shot = SynthTestShot(d / "actor", d / "takes" / Take(seed), kFrames, seed, d);
      ASSERT_EQ(shot.exit_code, 0) << shot.err;
    }
  }
  static void TearDownTestSuite() {
    fs::remove_all(*dir_);
    delete dir_;
  }
  static std::string Take(int seed) { return fmt::format("take{}", seed); }
  static std::string BatchArgs(const fs::path& takes, const fs::path& day) {
    const fs::path& d = *dir_;
    return fmt::format("batch --takes '{}' --actor '{}' --calibration '{}' --out '{}'",
                       takes.string(), (d / "actor").string(),
                       (d / "takes" / Take(1) / "calibration.yaml").string(), day.string());
  }
  static nlohmann::json ReadJson(const fs::path& file) {
    return nlohmann::json::parse(ReadFile(file));
  }
  static std::map<std::string, nlohmann::json> TakesByName(const fs::path& day) {
    std::map<std::string, nlohmann::json> takes;
    const nlohmann::json batch = ReadJson(day / "batch.json");
    for (const auto& t : batch["takes"]) takes[t["name"].get<std::string>()] = t;
    return takes;
  }
  static fs::path* dir_;
};

inline fs::path* BatchTest::dir_ = nullptr;

// The data files of every take of a day by take/relative path: what two
// schedulers must write alike. Not compared, as in tests/run_test.cc: the
// JSON summaries (wall times, paths, where the index came from) and the
// report pages.
inline std::map<std::string, std::string> DayData(const fs::path& day,
                                           const std::vector<std::string>& takes) {
  std::map<std::string, std::string> files;
  for (const std::string& take : takes) {
    for (const auto& e : fs::recursive_directory_iterator(day / take)) {
      if (!e.is_regular_file() || e.path().filename().string()[0] == '.') continue;
      const std::string rel = fs::relative(e.path(), day).string();
      if (e.path().extension() == ".json" || rel.find("/report/") != std::string::npos) continue;
      files[rel] = ReadFile(e.path());
    }
  }
  return files;
}

}  // namespace hmc
