// Command-line and input errors as a user meets them (issue 24, items 8 and
// 12): exit code 2 with one line that says what is wrong, never a raw
// library message.
#include <sys/stat.h>

#include <gtest/gtest.h>

#include "core/file_util.h"
#include "tests/cli_runner.h"
#include "tests/small_actor.h"

namespace hmc {
namespace {

namespace fs = std::filesystem;

TEST(CliErrorsTest, CommandLineErrorsExitTwoAndSayWhat) {
  const fs::path dir = FreshTestDir("hmc_cli_errors", 1);
  const CliResult unknown = RunHmc("frobnicate", dir);
  EXPECT_EQ(unknown.exit_code, 2);
  EXPECT_NE(unknown.err.find("unknown command 'hmc frobnicate'"), std::string::npos) << unknown.err;
  const CliResult nested = RunHmc("actor nope", dir);
  EXPECT_EQ(nested.exit_code, 2);
  EXPECT_NE(nested.err.find("'hmc actor nope'"), std::string::npos) << nested.err;
  const CliResult threads = RunHmc("--threads -1 actor check x", dir);
  EXPECT_EQ(threads.exit_code, 2);
  EXPECT_LT(threads.err.size(), 200u) << threads.err;  // no 300-digit bound
  EXPECT_EQ(RunHmc("solve --bogus", dir).exit_code, 2);
  EXPECT_EQ(RunHmc("--help", dir).exit_code, 0);
  fs::remove_all(dir);
}

// Issue 52: `hmc --version`, an unknown flag named with a suggestion (was
// "The following arguments were not expected: 60 --fps").
TEST(CliErrorsTest, VersionPrintsAndAnUnknownFlagIsNamedWithASuggestion) {
  const fs::path dir = FreshTestDir("hmc_cli_version", 1);
  const CliResult version = RunHmc("--version", dir);
  EXPECT_EQ(version.exit_code, 0);
  EXPECT_EQ(version.out.rfind("hmc 0.", 0), 0u) << version.out;
  const CliResult fps = RunHmc("run --fsp 60", dir);
  EXPECT_EQ(fps.exit_code, 2);
  EXPECT_NE(fps.err.find("unknown option --fsp; did you mean --fps?"), std::string::npos)
      << fps.err;
  // Both spellings reach the same flag: the error is then about the value.
  for (const std::string flag : {"--start_frame", "--start-frame"}) {
    const CliResult r = RunHmc("convert a.pc2 b.pc2 " + flag + " x", dir);
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_EQ(r.err.find("unknown option"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("start_frame"), std::string::npos) << r.err;
  }
  fs::remove_all(dir);
}

TEST(CliErrorsTest, InputsThatAreNotFilesAreInputErrors) {
  const fs::path dir = FreshTestDir("hmc_cli_not_files", 1);
  WriteSmallActor(dir, 1, 24, 20);
  ASSERT_EQ(::mkfifo((dir / "fifo.csv").c_str(), 0600), 0);
  fs::create_symlink(dir / "b.csv", dir / "a.csv");
  fs::create_symlink(dir / "a.csv", dir / "b.csv");
  fs::create_directories(dir / "folder.csv");
  for (const std::string input : {"fifo.csv", "a.csv", "folder.csv"}) {
    const CliResult r = RunHmc(fmt::format("solve --actor '{}' --bundles '{}' --out '{}'",
                                           (dir / "actor").string(), (dir / input).string(),
                                           (dir / "out.pc2").string()),
                               dir);
    EXPECT_EQ(r.exit_code, 2) << input << ": " << r.err;
    EXPECT_EQ(r.err.find("filesystem error"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(dir / "out.pc2"));
  }
  fs::remove_all(dir);
}

// Rays are in helmet space: without the head poses that place them in head
// space the solve refuses them, saying what is missing, and writes nothing.
TEST(CliErrorsTest, RaysWithoutHeadPosesAreRefused) {
  const fs::path dir = FreshTestDir("hmc_cli_rays", 1);
  WriteSmallActor(dir, 1, 24, 20);
  WriteFileAtomic(dir / "bundles.csv", "frame,marker,x,y,z\n");
  WriteFileAtomic(dir / "rays.csv", "frame,marker,camera,ox,oy,oz,dx,dy,dz\n");
  const CliResult r = RunHmc(fmt::format("solve --actor '{}' --bundles '{}' --rays '{}' --out '{}'",
                                         (dir / "actor").string(), (dir / "bundles.csv").string(),
                                         (dir / "rays.csv").string(), (dir / "out.pc2").string()),
                             dir);
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("--head_from_helmet"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find((dir / "rays.csv").string()), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "out.pc2"));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace hmc
