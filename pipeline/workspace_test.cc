#include "pipeline/workspace.h"

#include <unistd.h>

#include <stdexcept>

#include <gtest/gtest.h>

#include "core/error.h"
#include "core/file_util.h"
#include "core/temp_dir.h"
#include "pipeline/run_pipeline.h"

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
  Workspace work(dir.path() / "work", PipelineStages());
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
  Workspace work(dir.path() / "work", PipelineStages());
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
  Workspace work(dir.path() / "work", PipelineStages());
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

std::string ErrorOfClaim(const fs::path& root) {
  try {
    Workspace work(root, PipelineStages());
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

// A run killed while it wrote the workspace's mark left the mark's
// temporary and no mark; the next run claims the folder (before: "holds 1
// file(s) hmc run did not write (..hmc_workspace.tmp.PID.0)", seen in
// RunTest.KilledAtRandomMomentsResumesToTheSameBytes).
TEST(WorkspaceTest, AKillWhileTheMarkWasWrittenLeavesAClaimableFolder) {
  TempDir dir;
  const fs::path w = dir.path() / "W";
  fs::create_directories(w);
  WriteFileAtomic(w / "..hmc_workspace.tmp.123.0", "hmc run wor");
  EXPECT_EQ(ErrorOfClaim(w), "no error");
  EXPECT_TRUE(fs::exists(w / ".hmc_workspace"));
  EXPECT_FALSE(fs::exists(w / "..hmc_workspace.tmp.123.0"));
  // Another file of that shape but not the mark's is still not hmc's.
  const fs::path v = dir.path() / "V";
  fs::create_directories(v);
  WriteFileAtomic(v / ".notes.txt.tmp.123.0", "x");
  EXPECT_NE(ErrorOfClaim(v).find(".notes.txt.tmp.123.0"), std::string::npos);
}

// Issue 45, item 3: a folder holding files hmc run did not write is
// refused before any work, and every file is left where it was (before:
// `hmc run --out D` deleted D/track/my_notes.txt and D/report/*.pdf).
TEST(WorkspaceTest, FilesHmcRunDidNotWriteAreRefusedNeverDeleted) {
  TempDir dir;
  const fs::path d = dir.path() / "D";
  fs::create_directories(d / "track");
  fs::create_directories(d / "report");
  WriteFileAtomic(d / "track" / "my_notes.txt", "notes\n");
  WriteFileAtomic(d / "report" / "final_client_report.pdf", "x\n");
  const std::string error = ErrorOfClaim(d);
  EXPECT_NE(error.find("2 file(s) hmc run did not write"), std::string::npos) << error;
  EXPECT_NE(error.find("track/my_notes.txt"), std::string::npos) << error;
  EXPECT_NE(error.find("report/final_client_report.pdf"), std::string::npos) << error;
  EXPECT_EQ(ReadFile(d / "track" / "my_notes.txt"), "notes\n");
  EXPECT_EQ(ReadFile(d / "report" / "final_client_report.pdf"), "x\n");
  // Any folder of someone else's, too.
  fs::create_directories(dir.path() / "mine");
  WriteFileAtomic(dir.path() / "mine" / "budget.xlsx", "x");
  EXPECT_NE(ErrorOfClaim(dir.path() / "mine").find("budget.xlsx"), std::string::npos);
  // In a workspace: a file dropped into a complete stage's folder is not
  // the stage's, so the stage folder is not replaced over it.
  const fs::path w = dir.path() / "W";
  {
    Workspace work(w, PipelineStages());
    work.RunStage(Key("a"), [](const fs::path& out) {
      WriteFileAtomic(out / "tracks_2d.csv", "x\n");
      return nlohmann::json::object();
    });
  }
  // What Finder leaves in a folder it showed is not the user's work.
  WriteFileAtomic(w / "track" / ".DS_Store", "finder\n");
  EXPECT_EQ(ErrorOfClaim(w), "no error");
  WriteFileAtomic(w / "track" / "look_at_frame_12.txt", "!\n");
  EXPECT_NE(ErrorOfClaim(w).find("track/look_at_frame_12.txt"), std::string::npos);
  // Files beside the stage folders of a workspace are never touched: kept.
  fs::remove(w / "track" / "look_at_frame_12.txt");
  WriteFileAtomic(w / "README.txt", "the take of Monday\n");
  EXPECT_EQ(ErrorOfClaim(w), "no error");
}

// Issue 45, item 4: a stage whose recorded output is missing or changed is
// not complete (before: a deleted solve/mesh.pc2 left "solve complete").
TEST(WorkspaceTest, AStageWithAnOutputMissingOrChangedIsNotComplete) {
  TempDir dir;
  Workspace work(dir.path() / "work", PipelineStages());
  work.RunStage(Key("a"), [](const fs::path& d) {
    WriteFileAtomic(d / "tracks_2d.csv", "x\n");
    fs::create_directories(d / "sub");
    WriteFileAtomic(d / "sub" / "frame_1.png", "p\n");
    return nlohmann::json::object();
  });
  ASSERT_TRUE(work.IsComplete(Key("a")));
  const nlohmann::json outputs = work.ReadSummary("track")["outputs"];
  EXPECT_EQ(outputs.size(), 2u) << outputs.dump();
  EXPECT_TRUE(outputs.contains("sub/frame_1.png")) << outputs.dump();
  for (const char* file : {"tracks_2d.csv", "sub/frame_1.png"}) {
    const fs::path path = work.StageDir("track") / file;
    const std::string bytes = ReadFile(path);
    fs::remove(path);
    EXPECT_FALSE(work.IsComplete(Key("a"))) << file;
    WriteFileAtomic(path, bytes + "edited");
    EXPECT_FALSE(work.IsComplete(Key("a"))) << file;
    WriteFileAtomic(path, bytes);
    EXPECT_TRUE(work.IsComplete(Key("a"))) << file;
  }
}

// Issue 45, item 5: one run at a time per workspace (before: two runs
// deleted each other's partial folders).
TEST(WorkspaceTest, AWorkspaceInUseIsRefusedNamingThePid) {
  TempDir dir;
  const fs::path root = dir.path() / "work";
  {
    Workspace first(root, PipelineStages());
    const std::string error = ErrorOfClaim(root);
    EXPECT_NE(error.find(fmt::format("is in use by pid {}", getpid())), std::string::npos) << error;
  }
  EXPECT_EQ(ErrorOfClaim(root), "no error");  // released with the first
  EXPECT_EQ(ReadFile(root / ".hmc_lock"), "");
}

// Issue 45, second campaign: a workspace on a share that goes away mid-run
// leaves an empty local folder at its path. The stage's command recreates
// its folder there; the stage must not be written "complete" there, and
// the run resumes once the share is back.
TEST(WorkspaceTest, AWorkspaceThatDisappearsMidStageStopsAndResumesWhenBack) {
  TempDir dir;
  const fs::path root = dir.path() / "work";
  const fs::path away = dir.path() / "share_gone";
  Workspace work(root, PipelineStages());
  work.RunStage(Key("a"), [](const fs::path& d) {
    WriteFileAtomic(d / "out.txt", "a");
    return nlohmann::json::object();
  });
  std::string error = "no error";
  try {
    work.RunStage(Key("b"), [&](const fs::path& d) {
      fs::rename(root, away);         // the share goes
      fs::create_directories(root);   // its mount point, empty
      EnsureDirectory(d);             // as a stage's command does
      WriteFileAtomic(d / "out.txt", "b");
      return nlohmann::json::object();
    });
  } catch (const InputError& e) {
    error = e.what();
  }
  EXPECT_NE(error.find(root.string() + ": the workspace disappeared during the run"),
            std::string::npos)
      << error;
  EXPECT_TRUE(fs::is_empty(root));  // nothing written "complete" in its place
  EXPECT_THROW(work.CheckStillThere(), InputError);
  // The share comes back: its complete stage is there, the run goes on.
  fs::remove(root);
  fs::rename(away, root);
  EXPECT_NO_THROW(work.CheckStillThere());
  EXPECT_TRUE(work.IsComplete(Key("a")));
  work.RunStage(Key("b"), [](const fs::path& d) {
    WriteFileAtomic(d / "out.txt", "b");
    return nlohmann::json::object();
  });
  EXPECT_EQ(ReadFile(work.StageDir("track") / "out.txt"), "b");
}

}  // namespace
}  // namespace hmc
