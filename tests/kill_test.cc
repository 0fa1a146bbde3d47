// Fault injection (issue 24, Deliver 3; docs/reliability.md): `hmc solve`
// and `hmc index` killed with SIGKILL at random moments. Every output is at
// all times either the earlier run's bytes or the new run's complete bytes;
// the next run leaves no temporary file behind and gives the bytes of an
// uninterrupted run. (tests/run_test.cc does the same for `hmc run`.) The
// diagnostics JSON is left out: it records the index build time.
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <map>
#include <random>

#include <gtest/gtest.h>

#include "core/file_util.h"
#include "core/frame_data.h"
#include "core/mesh.h"
#include "tests/cli_runner.h"
#include "tests/small_actor.h"

namespace hmc {
namespace {

namespace fs = std::filesystem;

// Every file under `dir` (relative name -> bytes).
std::map<std::string, std::string> Files(const fs::path& dir) {
  std::map<std::string, std::string> files;
  if (!fs::exists(dir)) return files;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    if (e.is_regular_file()) files[fs::relative(e.path(), dir).string()] = ReadFile(e.path());
  }
  return files;
}

// Temporaries of atomic writes (`.NAME.tmp.PID.N`) anywhere under `dir`.
std::vector<std::string> Temporaries(const fs::path& dir) {
  std::vector<std::string> found;
  if (!fs::exists(dir)) return found;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    if (e.path().filename().string().find(".tmp.") != std::string::npos) {
      found.push_back(e.path().string());
    }
  }
  return found;
}

// Runs `hmc ARGS` with XDG_CACHE_HOME=cache and kills it with SIGKILL after
// `seconds`; returns whether it was killed (not finished before).
bool RunAndKill(const std::string& args, const fs::path& cache, double seconds) {
  const std::string command = fmt::format("XDG_CACHE_HOME='{}' exec '{}' {} >/dev/null 2>&1",
                                          cache.string(), HMC_BINARY, args);
  const pid_t pid = fork();
  if (pid < 0) return false;
  if (pid == 0) {
    execl("/bin/sh", "sh", "-c", command.c_str(), static_cast<char*>(nullptr));
    _exit(127);
  }
  usleep(static_cast<useconds_t>(seconds * 1e6));
  kill(pid, SIGKILL);
  int status = 0;
  waitpid(pid, &status, 0);
  return WIFSIGNALED(status);
}

// Runs `args` to completion in `scratch` (its own cache), returns seconds.
double TimedRun(const std::string& args, const fs::path& scratch) {
  const auto start = std::chrono::steady_clock::now();
  const CliResult r = RunHmc(args, scratch);
  EXPECT_EQ(r.exit_code, 0) << args << "\n" << r.err;
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// The kill loop shared by both tests: `earlier` and `expected` are the
// files of `watched` after the earlier run and after a whole new run.
void KillAndResume(const std::string& args, const fs::path& watched, const fs::path& cache,
                   const std::map<std::string, std::string>& earlier,
                   const std::map<std::string, std::string>& expected, double seconds, int seed,
                   const fs::path& scratch) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> when(0.02, std::max(0.05, seconds));
  int killed = 0;
  for (int attempt = 0; attempt < 5; ++attempt) {
    killed += RunAndKill(args, cache, when(rng));
    // Every output is whole: the earlier run's or the new one's.
    for (const auto& [name, content] : Files(watched)) {
      if (name.find(".tmp.") != std::string::npos) continue;  // the killed run's
      const bool is_earlier = earlier.count(name) && earlier.at(name) == content;
      const bool is_new = expected.count(name) && expected.at(name) == content;
      EXPECT_TRUE(is_earlier || is_new) << "attempt " << attempt << ": torn " << name;
    }
  }
  EXPECT_GE(killed, 1);
  // The next run: the bytes of an uninterrupted one, no temporaries left.
  fs::create_directories(scratch);
  const std::string finish = fmt::format("XDG_CACHE_HOME='{}' '{}' {} >'{}' 2>&1", cache.string(),
                                         HMC_BINARY, args, (scratch / "log.txt").string());
  ASSERT_EQ(std::system(finish.c_str()), 0) << ReadFile(scratch / "log.txt");
  EXPECT_EQ(Files(watched), expected);
  EXPECT_TRUE(Temporaries(watched).empty()) << Temporaries(watched).front();
  EXPECT_TRUE(Temporaries(cache).empty()) << Temporaries(cache).front();
}

TEST(KillTest, SolveKilledAtRandomMomentsKeepsOutputsWholeAndResumesToTheSameBytes) {
  for (const int seed : {1, 2}) {
    const fs::path d = FreshTestDir("hmc_kill_solve", seed);
    const Actor actor = WriteSmallActor(d, seed, 24, 20);
    std::vector<BundleFrame> frames;
    std::vector<JawFrame> jaw;
    DatasetShapeFrames(actor, &frames, &jaw);
    WriteBundlesCsv(d / "bundles.csv", frames);
    WriteJawCsv(d / "jaw.csv", jaw);
    auto args = [&](const fs::path& out, const std::string& method) {
      return fmt::format(
          "solve --actor '{}' --bundles '{}' --jaw '{}' --out '{}' --topology '{}' --method {} "
          "--nn.uv_resolution 256",
          (d / "actor").string(), (d / "bundles.csv").string(), (d / "jaw.csv").string(),
          (out / "mesh.pc2").string(), (out / "t.obj").string(), method);
    };
    // The new run's bytes, uninterrupted, with a cold cache.
    fs::create_directories(d / "ref");
    const double seconds = TimedRun(args(d / "out", "robust"), d / "ref");
    const auto expected = Files(d / "out");
    fs::rename(d / "out", d / "ref" / "out");
    // The earlier output: another method into the same folder.
    fs::create_directories(d / "early");
    TimedRun(args(d / "out", "blendshape"), d / "early");
    const auto earlier = Files(d / "out");
    ASSERT_NE(earlier.at("mesh.pc2"), expected.at("mesh.pc2"));
    KillAndResume(args(d / "out", "robust"), d / "out", d / "kill_cache", earlier, expected,
                  seconds, seed, d / "finish");
    fs::remove_all(d);
  }
}

TEST(KillTest, IndexKilledAtRandomMomentsKeepsTheCacheWholeAndResumesToTheSameBytes) {
  for (const int seed : {1, 2}) {
    const fs::path d = FreshTestDir("hmc_kill_index", seed);
    WriteSmallActor(d, seed, 24, 20);
    const fs::path actor = d / "actor";
    auto args = [&](int resolution) {
      return fmt::format("index --actor '{}' --into_package --nn.uv_resolution {}",
                         actor.string(), resolution);
    };
    // The new run's bytes, then the earlier package (other options).
    fs::create_directories(d / "ref");
    const double seconds = TimedRun(args(256), d / "ref");
    const auto expected = Files(actor);
    ASSERT_TRUE(expected.count("lgi_index.bin"));
    fs::create_directories(d / "early");
    TimedRun(args(128), d / "early");
    const auto earlier = Files(actor);
    ASSERT_NE(earlier.at("lgi_index.bin"), expected.at("lgi_index.bin"));
    KillAndResume(args(256), actor, d / "kill_cache", earlier, expected, seconds, seed,
                  d / "finish");
    fs::remove_all(d);
  }
}

}  // namespace
}  // namespace hmc
