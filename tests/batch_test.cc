// hmc batch (issue 49): a shoot day of short synthetic takes on this
// machine: bad takes fail with their reason while the others finish, a
// complete take is kept and a changed one redone, a list of takes with
// frame ranges, the plan a farm manager runs. The SLURM scheduler:
// tests/batch_slurm_test.cc.
#include <chrono>
#include <map>
#include <thread>

#include "core/tracks_2d.h"
#include "pipeline/svg_plot.h"
#include "tests/batch_fixture.h"

namespace hmc {
namespace {

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
  // A solve section with index options: the day's index is built with them
  // (DAY/.batch/index.yaml), and the solve stage's mesh export runs.
  WriteFileAtomic(d / "solve_index.yaml", "solve:\n  index:\n    max_edge_neighbours: 24\n");
  const std::string config = fmt::format(" --config '{}'", (d / "solve_index.yaml").string());
  const CliResult batch = RunHmc(BatchArgs(takes, day) + config + " --jobs 2", d);
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
  // Its review page written by the take's process and linked; a failed take
  // has none.
  EXPECT_TRUE(fs::is_regular_file(day / "good" / "review" / "index.html"));
  EXPECT_NE(page.find("href=\"good/review/index.html\""), std::string::npos);
  EXPECT_EQ(state["good"]["review"], "good/review/index.html");
  EXPECT_EQ(state["no_cam1"]["review"], "");
  EXPECT_NE(page.find("src=\"good/report/contact_sheet.png\""), std::string::npos);
  // The actor's index was built once, before the takes, and the take's
  // solve loaded it from the day's cache.
  const nlohmann::json diagnostics = ReadJson(day / "good" / "solve" / "diagnostics.json");
  EXPECT_EQ(diagnostics["index"]["from_cache"], true) << diagnostics["index"].dump();
  EXPECT_NE(ReadFile(day / "logs" / "index.log").find("built in"), std::string::npos);
  EXPECT_TRUE(fs::is_regular_file(day / "good" / "solve" / "mesh.pc2"));

  // Again: the complete take is kept (not started again), the failed ones
  // are retried.
  const std::string started = state["good"]["started"];
  const auto before = DayData(day, {"good"});
  std::this_thread::sleep_for(std::chrono::milliseconds(1100));  // a new start time differs
  const CliResult again = RunHmc(BatchArgs(takes, day) + config + " --jobs 2", d);
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
  // --plan: the commands a farm manager runs, nothing run.
  const CliResult plan = RunHmc(BatchArgs(list, day) + " --plan", d);
  ASSERT_EQ(plan.exit_code, 0) << plan.err;
  EXPECT_NE(plan.out.find("'index' '--actor'"), std::string::npos) << plan.out;
  EXPECT_NE(plan.out.find("--take 'first'"), std::string::npos) << plan.out;
  EXPECT_NE(plan.out.find("--take '" + Take(2) + "'"), std::string::npos) << plan.out;
  EXPECT_NE(plan.out.find("--day_report"), std::string::npos) << plan.out;
  EXPECT_FALSE(fs::exists(day / "first"));
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
  // The same day again is kept whole; a changed run config (same file)
  // is not taken for the old one.
  const std::string config = fmt::format(" --config '{}'", (d / "to_triangulate.yaml").string());
  const CliResult kept = RunHmc(BatchArgs(list, day) + config, d);
  ASSERT_EQ(kept.exit_code, 0) << kept.err;
  EXPECT_NE(kept.err.find("take first complete: kept"), std::string::npos) << kept.err;
  WriteFileAtomic(d / "to_triangulate.yaml", "run:\n  to: stabilize\nbatch:\n  jobs: 2\n");
  const CliResult redone = RunHmc(BatchArgs(list, day) + config, d);
  ASSERT_EQ(redone.exit_code, 0) << redone.err;
  EXPECT_EQ(redone.err.find("complete: kept"), std::string::npos) << redone.err;
  EXPECT_TRUE(fs::is_regular_file(day / "first" / "stabilize" / "summary.json"));
  const CliResult nothing_left = RunHmc(BatchArgs(list, day) + config + " --plan", d);
  EXPECT_EQ(nothing_left.out.find("--take"), std::string::npos) << nothing_left.out;
  // A bad list names the file and line.
  WriteFileAtomic(list, "takes:\n  - shot: takes/nowhere\n");
  const CliResult bad = RunHmc(BatchArgs(list, d / "list_day2"), d);
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.err.find("day_list.yaml:2"), std::string::npos) << bad.err;
  // A take may not take the name of the day's own files.
  WriteFileAtomic(list, fmt::format("takes:\n  - name: report.html\n    shot: takes/{}\n", Take(1)));
  const CliResult reserved = RunHmc(BatchArgs(list, d / "list_day2"), d);
  EXPECT_EQ(reserved.exit_code, 2);
  EXPECT_NE(reserved.err.find("day_list.yaml:2"), std::string::npos) << reserved.err;
  EXPECT_NE(reserved.err.find("'report.html'"), std::string::npos) << reserved.err;
}

// A take in frame chunks (--chunk-frames): its first pass calibrates from
// the whole take, each chunk tracks its frames (the second from 1 frame
// before its own), and the take's run merges the chunks' own frames into
// its track stage and runs the rest on the whole take. A killed chunk is
// redone with the merge alone, and the day comes out the same.
TEST_F(BatchTest, AChunkedTakeMergesItsChunksAndRedoesAKilledChunkAlone) {
  const fs::path& d = *dir_;
  const fs::path list = d / "chunk_takes.csv";
  WriteFileAtomic(list, fmt::format("shot\ntakes/{}\n", Take(2)));
  WriteFileAtomic(d / "chunk.yaml", "run:\n  to: stabilize\nbatch:\n  chunk_overlap: 1\n");
  const std::string config = fmt::format(" --config '{}'", (d / "chunk.yaml").string());
  const fs::path whole = d / "chunk_day_whole";
  const CliResult w = RunHmc(BatchArgs(list, whole) + config, d);
  ASSERT_EQ(w.exit_code, 0) << w.err;
  const fs::path day = d / "chunk_day";
  const CliResult plan = RunHmc(BatchArgs(list, day) + config + " --chunk-frames 2 --plan", d);
  ASSERT_EQ(plan.exit_code, 0) << plan.err;
  for (const char* unit : {"@calibrate'", "@chunk0'", "@chunk1'"}) {
    EXPECT_NE(plan.out.find("--take '" + Take(2) + unit), std::string::npos) << plan.out;
  }
  const CliResult c = RunHmc(BatchArgs(list, day) + config + " --chunk-frames 2 --jobs 2", d);
  ASSERT_EQ(c.exit_code, 0) << c.err;
  const nlohmann::json take = TakesByName(day)[Take(2)];
  EXPECT_EQ(take["state"], "done") << take.dump();
  ASSERT_EQ(take["chunks"].size(), 3u);
  for (const auto& unit : take["chunks"]) EXPECT_EQ(unit["state"], "done") << unit.dump();
  EXPECT_EQ(take["figures"]["frames"], kFrames);
  // The merged tracks are each chunk's own frames: frames 1-2 of chunk 0,
  // which started where the whole take does with the same calibration
  // (so its rows are the unchunked run's), and frame 3 of chunk 1, which
  // tracked frames 2-3.
  EXPECT_EQ(ReadFile(day / Take(2) / "calibrate" / "calibration.yaml"),
            ReadFile(whole / Take(2) / "calibrate" / "calibration.yaml"));
  const std::vector<Track2d> merged = ReadTracks2dCsv(day / Take(2) / "track" / "tracks_2d.csv");
  const std::vector<Track2d> unchunked =
      ReadTracks2dCsv(whole / Take(2) / "track" / "tracks_2d.csv");
  const fs::path chunks = day / ".batch" / "chunks" / Take(2);
  const std::vector<Track2d> chunk1 = ReadTracks2dCsv(chunks / "1" / "track" / "tracks_2d.csv");
  ASSERT_FALSE(chunk1.empty());
  EXPECT_EQ(chunk1.front().frame, 2);
  // (frame, camera, marker) -> pixel of the rows the merge must keep.
  std::map<std::string, Vec2> expected;
  for (const auto* rows : {&unchunked, &chunk1}) {
    for (const Track2d& r : *rows) {
      if ((rows == &unchunked) == (r.frame <= 2)) {
        expected[fmt::format("{} {} {}", r.frame, r.camera, r.marker)] = r.pixel;
      }
    }
  }
  EXPECT_EQ(merged.size(), expected.size());
  for (const Track2d& row : merged) {
    const std::string id = fmt::format("{} {} {}", row.frame, row.camera, row.marker);
    ASSERT_TRUE(expected.count(id)) << id;
    EXPECT_EQ(expected[id], row.pixel) << id;
  }

  // Chunk 1 killed before the take's merge ran (its state left running,
  // its track stage never finished): the same command redoes it and the
  // take, keeps the first pass and chunk 0, and the day comes out the same.
  const auto before = DayData(day, {Take(2)});
  WriteFileAtomic(day / ".batch" / "takes" / (Take(2) + "@chunk1.json"),
                  "{\"state\": \"running\", \"pid\": 0}\n");
  fs::remove(day / ".batch" / "takes" / (Take(2) + ".json"));
  fs::remove_all(chunks / "1" / "track");
  const CliResult again = RunHmc(BatchArgs(list, day) + config + " --chunk-frames 2 --jobs 2", d);
  ASSERT_EQ(again.exit_code, 0) << again.err;
  EXPECT_NE(again.err.find(Take(2) + "@calibrate complete: kept"), std::string::npos) << again.err;
  EXPECT_NE(again.err.find(Take(2) + "@chunk0 complete: kept"), std::string::npos) << again.err;
  EXPECT_NE(again.err.find(Take(2) + "@chunk1 started"), std::string::npos) << again.err;
  EXPECT_EQ(DayData(day, {Take(2)}), before);
}

}  // namespace
}  // namespace hmc
