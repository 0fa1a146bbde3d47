#include "core/file_util.h"

#include <filesystem>
#include <fstream>
#include <stdexcept>

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

}  // namespace
}  // namespace hmc
