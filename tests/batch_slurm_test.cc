// hmc batch --scheduler slurm (issue 49) on a real one-node SLURM cluster
// that the test starts and stops (tests/slurm_fixture.h). Labelled `slow`
// (tests/CMakeLists.txt): a local batch, a SLURM batch and a redone take,
// 16 s on a quiet 2-core machine, 75-95 s under a load average of 15.
#include <chrono>
#include <thread>

#include "pipeline/subprocess.h"
#include "tests/batch_fixture.h"
#include "tests/slurm_fixture.h"

namespace hmc {
namespace {

// A real one-node SLURM cluster: the same day, one take of it in frame
// chunks (--chunk-frames: a first pass, two chunks and a merge, each a task
// of its own), submitted as jobs gives the local scheduler's bytes; a task
// cancelled mid-run with scancel is the only one the same command submits
// again, and the day then matches.
TEST_F(BatchTest, SlurmGivesTheLocalBytesAndRedoesACancelledTakeAlone) {
  const std::string missing = SlurmCluster::Missing();
  if (!missing.empty()) {
    GTEST_SKIP() << "SLURM test skipped: " << missing
                 << " not installed (Debian: apt-get install slurm-wlm munge; scripts/setup "
                    "installs them)";
  }
  const fs::path& d = *dir_;
  const std::vector<std::string> takes = {Take(1), Take(2), Take(3)};
  // Take 1 whole (3 frames) in chunks of 2 frames, the second tracked from
  // 1 frame before its own; the others 2 frames long: one task each.
  const fs::path list = d / "slurm_takes.csv";
  WriteFileAtomic(list, fmt::format("name,shot,frames\n{0},takes/{0},\n{1},takes/{1},1:2\n"
                                    "{2},takes/{2},1:2\n",
                                    Take(1), Take(2), Take(3)));
  // Up to the solve: the report pages are not compared (DayData), and the
  // test stays short.
  const fs::path config = d / "to_solve.yaml";
  WriteFileAtomic(config, "run:\n  to: solve\nbatch:\n  chunk_overlap: 1\n");
  const std::string to_solve = fmt::format(" --config '{}' --chunk-frames 2", config.string());
  const fs::path local = d / "day_local";
  const CliResult l = RunHmc(BatchArgs(list, local) + to_solve + " --jobs 2", d);
  ASSERT_EQ(l.exit_code, 0) << l.err;
  ASSERT_EQ(TakesByName(local)[Take(1)]["chunks"].size(), 3u);  // first pass, 2 chunks

  SlurmCluster cluster(fs::path("/tmp") / fmt::format("hmcs{}", getpid()));
  ASSERT_TRUE(cluster.Ok()) << cluster.Error();
  const fs::path day = d / "day_slurm";
  const std::string submit = BatchArgs(list, day) + to_solve + " --scheduler slurm";
  const CliResult s = RunHmc(submit, d);
  ASSERT_EQ(s.exit_code, 0) << s.err;
  const nlohmann::json jobs = ReadJson(day / ".batch" / "slurm.json");
  EXPECT_NE(jobs["first"], "");  // the chunked take's first pass
  EXPECT_NE(jobs["merge"], "");  // and its merge
  // Cancel the task of the last take once it runs.
  const std::string task = fmt::format("{}_{}", jobs["array"].get<std::string>(),
                                       jobs["tasks"][Take(3)].get<int>());
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
  // batch.json, rewritten by --status --wait, says so too.
  EXPECT_EQ(state[Take(3)]["state"], "incomplete") << waited.out;
  EXPECT_NE(waited.out.find(Take(3)), std::string::npos);

  // The same command again: only the cancelled take is submitted.
  const CliResult again = RunHmc(submit + " --wait", d);
  EXPECT_EQ(again.exit_code, 0) << again.out << again.err;
  const nlohmann::json resubmitted = ReadJson(day / ".batch" / "slurm.json");
  EXPECT_EQ(resubmitted["tasks"], nlohmann::json({{Take(3), jobs["tasks"][Take(3)]}}));
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
