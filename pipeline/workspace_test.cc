#include "pipeline/workspace.h"

#include <stdexcept>

#include <gtest/gtest.h>

#include "core/file_util.h"
#include "core/temp_dir.h"

namespace hmc {
namespace {

namespace fs = std::filesystem;

StageKey Key(const std::string& input_text) {
  StageKey key;
  key.stage = "track";
  key.AddInputText("in", input_text);
  key.options = "0";
  return key;
}

TEST(WorkspaceTest, AStageIsCompleteOnlyWithItsSummaryAndTheSameKey) {
  TempDir dir;
  Workspace work(dir.path() / "work");
  EXPECT_FALSE(work.IsComplete(Key("a")));
  work.RunStage(Key("a"), [](const fs::path& d) {
    WriteFileAtomic(d / "tracks_2d.csv", "x\n");
    return nlohmann::json{{"rows", 1}};
  });
  EXPECT_TRUE(work.IsComplete(Key("a")));
  EXPECT_FALSE(work.IsComplete(Key("b")));
  EXPECT_EQ(ReadFile(work.StageDir("track") / "tracks_2d.csv"), "x\n");
  EXPECT_EQ(work.ReadSummary("track")["report"]["rows"], 1);
  // Without the summary (killed before it was written) it is not complete.
  fs::remove(work.StageDir("track") / "summary.json");
  EXPECT_FALSE(work.IsComplete(Key("a")));
}

TEST(WorkspaceTest, AFailedStageLeavesTheOldFolderAndNoPartialOne) {
  TempDir dir;
  Workspace work(dir.path() / "work");
  work.RunStage(Key("a"), [](const fs::path& d) {
    WriteFileAtomic(d / "out.txt", "old");
    return nlohmann::json::object();
  });
  EXPECT_THROW(work.RunStage(Key("b"),
                             [](const fs::path& d) -> nlohmann::json {
                               WriteFileAtomic(d / "out.txt", "half");
                               throw std::runtime_error("killed");
                             }),
               std::runtime_error);
  EXPECT_EQ(ReadFile(work.StageDir("track") / "out.txt"), "old");
  EXPECT_TRUE(work.IsComplete(Key("a")));
  EXPECT_FALSE(fs::exists(dir.path() / "work" / ".track.partial"));
}

TEST(WorkspaceTest, LeftoversOfAKilledRunAreRemovedAndTheRedoIsWhole) {
  TempDir dir;
  Workspace work(dir.path() / "work");
  const fs::path partial = dir.path() / "work" / ".track.partial";
  fs::create_directories(partial);
  WriteFileAtomic(partial / ".tracks_2d.csv.tmp.123.0", "stale");
  WriteFileAtomic(partial / "stale.txt", "stale");
  work.RunStage(Key("a"), [](const fs::path& d) {
    WriteFileAtomic(d / "tracks_2d.csv", "new");
    return nlohmann::json::object();
  });
  EXPECT_FALSE(fs::exists(partial));
  EXPECT_FALSE(fs::exists(work.StageDir("track") / "stale.txt"));
  EXPECT_FALSE(fs::exists(work.StageDir("track") / ".tracks_2d.csv.tmp.123.0"));
  EXPECT_EQ(ReadFile(work.StageDir("track") / "tracks_2d.csv"), "new");
}

TEST(WorkspaceTest, FolderHashesFollowContentNotTime) {
  TempDir dir;
  fs::create_directories(dir.path() / "a" / "sub");
  WriteFileAtomic(dir.path() / "a" / "x.txt", "1");
  WriteFileAtomic(dir.path() / "a" / "sub" / "y.txt", "2");
  const uint64_t h = HashPath(dir.path() / "a");
  WriteFileAtomic(dir.path() / "a" / "x.txt", "1");  // rewritten, same bytes
  EXPECT_EQ(HashPath(dir.path() / "a"), h);
  WriteFileAtomic(dir.path() / "a" / ".hidden", "ignored");
  EXPECT_EQ(HashPath(dir.path() / "a"), h);
  WriteFileAtomic(dir.path() / "a" / "sub" / "y.txt", "3");
  EXPECT_NE(HashPath(dir.path() / "a"), h);
}

}  // namespace
}  // namespace hmc
