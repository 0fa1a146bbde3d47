// hmc batch (issue 49): a shoot day of short synthetic takes, locally and
// on a real one-node SLURM cluster started by the test (tests/
// slurm_fixture.h): bad takes fail with their reason while the others
// finish, a complete take is kept, SLURM gives the local scheduler's bytes,
// and a task cancelled with scancel is redone alone by the same command.
#include <signal.h>

#include <chrono>
#include <cstdio>
#include <map>
#include <thread>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "core/file_util.h"
#include "pipeline/subprocess.h"
#include "pipeline/svg_plot.h"
#include "tests/cli_runner.h"
#include "tests/slurm_fixture.h"
#include "tests/small_actor.h"

namespace hmc {
namespace {

namespace fs = std::filesystem;

constexpr int kFrames = 3;

class BatchTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new fs::path(FreshTestDir("hmc_batch_test", 49));
    const fs::path& d = *dir_;
    ASSERT_EQ(RunHmc(fmt::format("actor synth --out '{}' --seed 7 --grid_u 96 --grid_v 80 "
                                 "--dataset_inbetweens false --dataset_combos false",
                                 (d / "actor").string()),
                     d)
                  .exit_code,
              0);
    // Three takes of different seeds.
    for (int seed : {1, 2, 3}) {
      const CliResult shot = RunHmc(
          fmt::format("synth shot --actor '{}' --out '{}' --frames {} --seed {} --contact_frames 0",
                      (d / "actor").string(), (d / "takes" / Take(seed)).string(), kFrames, seed),
          d);
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

fs::path* BatchTest::dir_ = nullptr;

// The data files of every take of a day by take/relative path: what two
// schedulers must write alike. Not compared, as in tests/run_test.cc: the
// JSON summaries (wall times, paths, where the index came from) and the
// report pages.
std::map<std::string, std::string> DayData(const fs::path& day,
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

TEST_F(BatchTest, BadTakesFailWithTheirReasonTheOthersFinishAndCompleteTakesAreKept) {
  const fs::path& d = *dir_;
  const fs::path takes = d / "bad_day_takes";
  fs::create_directories(takes);
  fs::copy(d / "takes" / Take(1), takes / "good", fs::copy_options::recursive);
  // A missing camera, a corrupt video, footage without helmet tags.
  fs::copy(d / "takes" / Take(2), takes / "no_cam1", fs::copy_options::recursive);
  fs::remove(takes / "no_cam1" / "cam1.mkv");
  fs::copy(d / "takes" / Take(2), takes / "corrupt", fs::copy_options::recursive);
  const std::string video = ReadFile(takes / "corrupt" / "cam0.mkv");
  WriteFileAtomic(takes / "corrupt" / "cam0.mkv", video.substr(0, video.size() / 50));
  const CliResult shot = RunHmc(
      fmt::format("synth shot --actor '{}' --out '{}' --frames 2 --seed 4 --contact_frames 0 "
                  "--render.tag_white 0.04",
                  (d / "actor").string(), (takes / "no_tags").string()),
      d);
  ASSERT_EQ(shot.exit_code, 0) << shot.err;
  fs::create_directories(takes / "notes");  // no footage: not a take
  const fs::path day = d / "bad_day";
  const CliResult batch = RunHmc(BatchArgs(takes, day) + " --jobs 2", d);
  EXPECT_EQ(batch.exit_code, 1) << batch.err;  // some takes failed
  auto state = TakesByName(day);
  ASSERT_EQ(state.size(), 4u);
  EXPECT_EQ(state["good"]["state"], "done") << state["good"].dump();
  const std::map<std::string, std::string> reasons = {
      {"no_cam1", "no footage for camera cam1"},
      {"corrupt", "cam0.mkv"},
      {"no_tags", "no helmet tag"}};
  const std::string page = ReadFile(day / "report.html");
  for (const auto& [take, reason] : reasons) {
    EXPECT_EQ(state[take]["state"], "failed") << take;
    EXPECT_NE(state[take]["reason"].get<std::string>().find(reason), std::string::npos)
        << take << ": " << state[take]["reason"];
    EXPECT_TRUE(fs::is_regular_file(day / state[take]["log"].get<std::string>())) << take;
    EXPECT_NE(page.find(take), std::string::npos) << take;
    EXPECT_NE(page.find(HtmlEscape(state[take]["reason"].get<std::string>())), std::string::npos) << take;
  }
  // The good take against its truth, and linked from the day report.
  EXPECT_LT(state["good"]["figures"]["truth_face_mean_mm"].get<double>(), 0.3);
  EXPECT_EQ(state["good"]["figures"]["frames"], kFrames);
  EXPECT_NE(page.find("href=\"good/report/report.html\""), std::string::npos);
  EXPECT_NE(page.find("src=\"good/report/contact_sheet.png\""), std::string::npos);

  // Again: the complete take is kept (not started again), the failed ones
  // are retried.
  const std::string started = state["good"]["started"];
  const auto before = DayData(day, {"good"});
  std::this_thread::sleep_for(std::chrono::milliseconds(1100));  // a new start time differs
  const CliResult again = RunHmc(BatchArgs(takes, day) + " --jobs 2", d);
  EXPECT_EQ(again.exit_code, 1) << again.err;
  EXPECT_NE(again.err.find("take good complete: kept"), std::string::npos) << again.err;
  state = TakesByName(day);
  EXPECT_EQ(state["good"]["started"], started);
  EXPECT_NE(state["no_cam1"]["started"], "");
  EXPECT_EQ(DayData(day, {"good"}), before);
}

// The list form: a YAML list with a take's own frame range and a name
// other than its folder's.
TEST_F(BatchTest, AListOfTakesWithFrameRanges) {
  const fs::path& d = *dir_;
  const fs::path list = d / "day_list.yaml";
  WriteFileAtomic(list, fmt::format("takes:\n  - name: first\n    shot: takes/{}\n    frames: "
                                    "\"2:3\"\n  - shot: takes/{}\n",
                                    Take(1), Take(2)));
  const fs::path day = d / "list_day";
  const CliResult batch = RunHmc(BatchArgs(list, day) + " --jobs 2 --to triangulate", d);
  // --to is not a batch flag: the run options come from the config.
  EXPECT_EQ(batch.exit_code, 2);
  WriteFileAtomic(d / "to_triangulate.yaml", "run:\n  to: triangulate\nbatch:\n  jobs: 2\n");
  const CliResult ok = RunHmc(
      BatchArgs(list, day) + fmt::format(" --config '{}'", (d / "to_triangulate.yaml").string()),
      d);
  ASSERT_EQ(ok.exit_code, 0) << ok.err;
  auto state = TakesByName(day);
  ASSERT_EQ(state.size(), 2u);
  EXPECT_EQ(state["first"]["figures"]["frames"], 2);
  EXPECT_EQ(state[Take(2)]["figures"]["frames"], kFrames);
  EXPECT_FALSE(fs::exists(day / "first" / "solve"));
  // A bad list names the file and line.
  WriteFileAtomic(list, "takes:\n  - shot: takes/nowhere\n");
  const CliResult bad = RunHmc(BatchArgs(list, d / "list_day2"), d);
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.err.find("day_list.yaml:2"), std::string::npos) << bad.err;
}

// A real one-node SLURM cluster: the same day submitted as jobs gives the
// local scheduler's bytes; a task cancelled mid-run with scancel is the
// only one the same command submits again, and the day then matches.
TEST_F(BatchTest, SlurmGivesTheLocalBytesAndRedoesACancelledTakeAlone) {
  const std::string missing = SlurmCluster::Missing();
  if (!missing.empty()) {
    GTEST_SKIP() << "SLURM test skipped: " << missing
                 << " not installed (Debian: apt-get install slurm-wlm munge; scripts/setup "
                    "installs them)";
  }
  const fs::path& d = *dir_;
  const std::vector<std::string> takes = {Take(1), Take(2), Take(3)};
  // Up to the solve: the report pages are not compared (DayData), and the
  // test stays short.
  const fs::path config = d / "to_solve.yaml";
  WriteFileAtomic(config, "run:\n  to: solve\n");
  const std::string to_solve = fmt::format(" --config '{}'", config.string());
  const fs::path local = d / "day_local";
  const CliResult l = RunHmc(BatchArgs(d / "takes", local) + to_solve + " --jobs 2", d);
  ASSERT_EQ(l.exit_code, 0) << l.err;

  SlurmCluster cluster(fs::path("/tmp") / fmt::format("hmcs{}", getpid()));
  ASSERT_TRUE(cluster.Ok()) << cluster.Error();
  const fs::path day = d / "day_slurm";
  const std::string submit = BatchArgs(d / "takes", day) + to_solve + " --scheduler slurm";
  const CliResult s = RunHmc(submit, d);
  ASSERT_EQ(s.exit_code, 0) << s.err;
  const nlohmann::json jobs = ReadJson(day / ".batch" / "slurm.json");
  // Cancel the task of the last take once it runs.
  const std::string task = fmt::format("{}_{}", jobs["array"].get<std::string>(), 2);
  bool cancelled = false;
  for (int i = 0; i < 600 && !cancelled; ++i) {
    std::string out;
    CaptureProcess({"squeue", "-h", "-r", "-j", task, "-o", "%T"}, &out);
    if (out.rfind("RUNNING", 0) == 0) {
      std::this_thread::sleep_for(std::chrono::milliseconds(500));  // mid-run
      cancelled = CaptureProcess({"scancel", task}, nullptr) == 0;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  ASSERT_TRUE(cancelled);
  const CliResult waited = RunHmc(fmt::format("batch --status '{}' --wait", day.string()), d);
  EXPECT_EQ(waited.exit_code, 1) << waited.out << waited.err;
  auto state = TakesByName(day);
  EXPECT_EQ(state[Take(1)]["state"], "done") << waited.out;
  EXPECT_EQ(state[Take(2)]["state"], "done") << waited.out;
  EXPECT_NE(state[Take(3)]["state"], "done") << waited.out;
  EXPECT_NE(waited.out.find(Take(3)), std::string::npos);

  // The same command again: only the cancelled take is submitted.
  const CliResult again = RunHmc(submit + " --wait", d);
  EXPECT_EQ(again.exit_code, 0) << again.out << again.err;
  const nlohmann::json resubmitted = ReadJson(day / ".batch" / "slurm.json");
  EXPECT_EQ(resubmitted["tasks"], nlohmann::json({{Take(3), 2}}));
  state = TakesByName(day);
  for (const std::string& take : takes) EXPECT_EQ(state[take]["state"], "done") << take;
  EXPECT_EQ(ReadJson(day / "batch.json")["scheduler"], "slurm");
  const auto expected = DayData(local, takes);
  const auto got = DayData(day, takes);
  EXPECT_EQ(got.size(), expected.size());
  for (const auto& [file, bytes] : expected) {
    EXPECT_TRUE(got.count(file) && got.at(file) == bytes) << file << " differs";
  }
}

}  // namespace
}  // namespace hmc
