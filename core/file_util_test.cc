#include "core/file_util.h"

#include <filesystem>
#include <fstream>
#include <stdexcept>

#include <sys/stat.h>
#include <unistd.h>

#include <fmt/format.h>

#include <gtest/gtest.h>

#include "core/error.h"

namespace hmc {
namespace {

namespace fs = std::filesystem;

fs::path FreshDir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

TEST(FileUtilTest, AtomicWriteReplacesContents) {
  const fs::path dir = FreshDir("hmc_file_util_replace");
  const fs::path file = dir / "out.txt";
  WriteFileAtomic(file, "first");
  WriteFileAtomic(file, "second");
  EXPECT_EQ(ReadFile(file), "second");
  EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 1);
}

TEST(FileUtilTest, FailedWriteKeepsOldFileAndLeavesNoTemporary) {
  const fs::path dir = FreshDir("hmc_file_util_fail");
  const fs::path file = dir / "out.txt";
  WriteFileAtomic(file, "precious");
  EXPECT_THROW(WriteFileAtomic(file,
                               [](std::ostream& out) {
                                 out << "half";
                                 throw std::runtime_error("interrupted");
                               }),
               std::runtime_error);
  EXPECT_EQ(ReadFile(file), "precious");
  EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 1);
}

TEST(FileUtilTest, ErrorsNameTheFile) {
  const fs::path missing = fs::temp_directory_path() / "hmc_no_such_dir" / "x.txt";
  try {
    WriteFileAtomic(missing, "x");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), missing);
  }
  try {
    ReadFile(missing);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("does not exist"), std::string::npos);
  }
}


// issue 24 item 8: what is not a regular file is refused with what it is,
// never a raw filesystem error.
TEST(FileUtilTest, InputsThatAreNotFilesSayWhatTheyAre) {
  const fs::path dir = FreshDir("hmc_file_util_kinds");
  fs::create_directories(dir / "folder");
  ASSERT_EQ(::mkfifo((dir / "fifo").c_str(), 0600), 0);
  fs::create_symlink(dir / "loop_b", dir / "loop_a");
  fs::create_symlink(dir / "loop_a", dir / "loop_b");
  fs::create_symlink(dir / "nothing", dir / "dangling");
  const auto message = [](const fs::path& p) {
    try {
      ReadFile(p);
    } catch (const InputError& e) {
      EXPECT_EQ(e.file(), p);
      return std::string(e.what());
    }
    return std::string("read");
  };
  EXPECT_NE(message(dir / "folder").find("is a folder"), std::string::npos);
  EXPECT_NE(message(dir / "fifo").find("FIFO"), std::string::npos);  // and does not block
  EXPECT_NE(message(dir / "loop_a").find("loop of symbolic links"), std::string::npos);
  EXPECT_NE(message(dir / "dangling").find("link to nothing"), std::string::npos);
  EXPECT_NE(message("/dev/null").find("is a device"), std::string::npos);
  EXPECT_EQ(DescribeUnreadable(dir / "folder" / ".." / "folder"), "is a folder, not a file");
  WriteFileAtomic(dir / "real", "x");
  fs::create_symlink(dir / "real", dir / "link");
  EXPECT_EQ(ReadFile(dir / "link"), "x");
  fs::remove_all(dir);
}

// issue 24 item 12: temporaries of a killed writer are removed by the next
// write of the same output; those of other outputs and of live processes
// are left alone.
TEST(FileUtilTest, StaleTemporariesOfTheSameOutputAreRemoved) {
  const fs::path dir = FreshDir("hmc_file_util_stale");
  const long dead_pid = 2147483646;  // above any pid_max: no such process
  const fs::path stale = dir / fmt::format(".mesh.pc2.tmp.{}.3", dead_pid);
  const fs::path other = dir / fmt::format(".other.csv.tmp.{}.0", dead_pid);
  const fs::path live = dir / fmt::format(".mesh.pc2.tmp.{}.0", getppid());
  for (const fs::path& p : {stale, other, live}) std::ofstream(p) << "partial";
  WriteFileAtomic(dir / "mesh.pc2", "whole");
  EXPECT_FALSE(fs::exists(stale));
  EXPECT_TRUE(fs::exists(other));
  EXPECT_TRUE(fs::exists(live));
  EXPECT_EQ(ReadFile(dir / "mesh.pc2"), "whole");
  fs::remove_all(dir);
}

// issue 24 item 5: a folder is written whole or not at all; a re-run
// replaces it entirely; folders hmc did not write, other commands' folders
// and folders inside an actor package are refused before anything runs.
TEST(FileUtilTest, FoldersAreWrittenWholeOrRefused) {
  const fs::path dir = FreshDir("hmc_file_util_folder");
  const fs::path out = dir / "shot";
  auto write = [](int n) {
    return [n](const fs::path& d) {
      for (int i = 0; i < n; ++i) WriteFileAtomic(d / fmt::format("f{}.txt", i), "x");
    };
  };
  WriteFolderAtomic(out, "hmc test", write(3));
  EXPECT_TRUE(fs::exists(out / "f2.txt"));
  WriteFolderAtomic(out, "hmc test", write(1));
  EXPECT_TRUE(fs::exists(out / "f0.txt"));
  EXPECT_FALSE(fs::exists(out / "f1.txt"));  // nothing of the earlier run
  // A failing write leaves the previous folder and no temporary.
  EXPECT_THROW(WriteFolderAtomic(out, "hmc test",
                                 [](const fs::path& d) {
                                   WriteFileAtomic(d / "half.txt", "x");
                                   throw InputError("failed half way");
                                 }),
               InputError);
  EXPECT_TRUE(fs::exists(out / "f0.txt"));
  EXPECT_FALSE(fs::exists(out / "half.txt"));
  int entries = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir)) ++entries;
  EXPECT_EQ(entries, 1);
  // Refusals, decided before `write` runs.
  bool ran = false;
  auto mark = [&](const fs::path&) { ran = true; };
  EXPECT_THROW(WriteFolderAtomic(out, "hmc other", mark), InputError);
  fs::create_directories(dir / "mine");
  WriteFileAtomic(dir / "mine" / "notes.txt", "keep");
  EXPECT_THROW(WriteFolderAtomic(dir / "mine", "hmc test", mark), InputError);
  WriteFileAtomic(dir / "actor.yaml", "name: a\n");
  EXPECT_THROW(WriteFolderAtomic(dir / "inside", "hmc test", mark), InputError);
  EXPECT_FALSE(ran);
  EXPECT_EQ(ReadFile(dir / "mine" / "notes.txt"), "keep");
  fs::remove_all(dir);
}

// issue 24 item 6: output paths are checked, and their folders made, first.
TEST(FileUtilTest, OutputPathsAreCheckedAndTheirFoldersMade) {
  const fs::path dir = FreshDir("hmc_file_util_outputs");
  PrepareOutputPath(dir / "a" / "b" / "d.json", "--diagnostics");
  EXPECT_TRUE(fs::is_directory(dir / "a" / "b"));
  EXPECT_THROW(PrepareOutputPath(dir / "a", "--out"), InputError);  // a folder
  WriteFileAtomic(dir / "file", "x");
  EXPECT_THROW(PrepareOutputPath(dir / "file", "--out", /*folder=*/true), InputError);
  EXPECT_THROW(PrepareOutputPath(dir / "file" / "d.json", "--diagnostics"), InputError);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace hmc
