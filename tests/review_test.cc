// hmc review and track fixes (issue 48, docs/review.md) on a short
// synthetic shot of a small actor: the page is written with its proxies and
// data; in a real browser (Debian's chromium, headless, the page's test
// mode) it loads without a console error, moving the cursor changes the
// footage frame and the mesh, and a scripted rename exports the
// track_fixes.csv the tracks predict; `hmc run --from track --fixes`
// applies it and records it; an `absent` fix followed by one `rename`
// brings a marker back and the tracker carries it on to the later frames.
#include <cstdio>
#include <cstdlib>
#include <map>
#include <tuple>
#include <utility>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "core/file_util.h"
#include "core/mesh_sequence.h"
#include "core/types.h"
#include "core/tracks_2d.h"
#include "tests/cli_runner.h"
#include "tests/small_actor.h"

namespace hmc {
namespace {

namespace fs = std::filesystem;

constexpr int kFrames = 6;

class ReviewTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new fs::path(FreshTestDir("hmc_review_test", 11));
    const fs::path& d = *dir_;
    ASSERT_EQ(SynthTestActor(d / "actor", d).exit_code, 0);
    const CliResult shot = SynthTestShot(d / "actor", d / "shot", kFrames, 5, d);
    ASSERT_EQ(shot.exit_code, 0) << shot.err;
    const CliResult run = RunHmc(RunArgs(), d);
    ASSERT_EQ(run.exit_code, 0) << run.err;
    // The run's tracks before any test applies a fix to the workspace.
    fs::copy_file(d / "work" / "track" / "tracks_2d.csv", d / "tracks_unfixed.csv");
  }
  static void TearDownTestSuite() {
    fs::remove_all(*dir_);
    delete dir_;
  }
  static std::string RunArgs() {
    const fs::path& d = *dir_;
    return fmt::format("run --shot '{}' --actor '{}' --calibration '{}' --out '{}'",
                       (d / "shot").string(), (d / "actor").string(),
                       (d / "shot" / "calibration.yaml").string(), (d / "work").string());
  }
  static fs::path* dir_;
};

fs::path* ReviewTest::dir_ = nullptr;

// Chromium, if installed: Debian's package installs /usr/bin/chromium.
std::string Chromium() {
  for (const char* path : {"/usr/bin/chromium", "/usr/bin/chromium-browser"}) {
    if (fs::exists(path)) return path;
  }
  return "";
}

// The rows of one frame and camera, in the file's order (sorted by marker).
std::vector<Track2d> RowsAt(const std::vector<Track2d>& tracks, int frame, const std::string& camera) {
  std::vector<Track2d> rows;
  for (const Track2d& t : tracks) {
    if (t.frame == frame && t.camera == camera) rows.push_back(t);
  }
  return rows;
}

TEST_F(ReviewTest, ThePageWorksInARealBrowserAndItsFixesApply) {
  const fs::path& d = *dir_;
  const fs::path work = d / "work";
  const CliResult review = RunHmc(fmt::format("review --work '{}'", work.string()), d);
  ASSERT_EQ(review.exit_code, 0) << review.err;
  const fs::path page = work / "review";
  for (const char* f : {"index.html", "review.js", "three.min.js", "OrbitControls.js", "data/meta.js",
                        "data/topology.js", "data/chunk_00000.js"}) {
    EXPECT_TRUE(fs::is_regular_file(page / f)) << f;
  }
  // A proxy per camera and frame, far smaller than the footage.
  int64_t proxy_bytes = 0, proxies = 0;
  for (const auto& e : fs::recursive_directory_iterator(page / "footage")) {
    if (!e.is_regular_file()) continue;
    ++proxies;
    proxy_bytes += static_cast<int64_t>(e.file_size());
  }
  EXPECT_EQ(proxies, 2 * kFrames);
  int64_t footage_bytes = 0;
  for (const auto& e : fs::recursive_directory_iterator(d / "shot")) {
    const std::string name = e.path().filename().string();
    if (e.is_regular_file() && name.rfind("cam", 0) == 0) footage_bytes += static_cast<int64_t>(e.file_size());
  }
  EXPECT_LT(proxy_bytes, footage_bytes / 4);

  const std::string chromium = Chromium();
  if (chromium.empty()) GTEST_SKIP() << "chromium is not installed (scripts/setup installs it): the page was not checked in a browser";
  const fs::path dom = d / "dom.html";
  const std::string command = fmt::format(
      "timeout 50 '{}' --headless --no-sandbox --enable-unsafe-swiftshader --user-data-dir='{}' "
      "--window-size=1400,1000 --virtual-time-budget=20000 --dump-dom 'file://{}?test=1' >'{}' 2>/dev/null",
      chromium, (d / "chromium_profile").string(), fs::absolute(page / "index.html").string(), dom.string());
  ASSERT_EQ(std::system(command.c_str()), 0) << command;
  const std::string html = ReadFile(dom);
  const std::string open = "<div id=\"test_results\" data-done=\"1\">";
  const size_t from = html.find(open);
  const size_t to = from == std::string::npos ? from : html.find("</div>", from);
  ASSERT_NE(to, std::string::npos) << "the page's test mode did not finish: " << html.substr(0, 2000);
  std::string text = html.substr(from + open.size(), to - from - open.size());
  for (const auto& [entity, c] : std::vector<std::pair<std::string, std::string>>{{"&quot;", "\""}, {"&amp;", "&"}}) {
    for (size_t at; (at = text.find(entity)) != std::string::npos;) text.replace(at, entity.size(), c);
  }
  const nlohmann::json r = nlohmann::json::parse(text);
  nlohmann::json shown = r;
  shown.erase("mesh_sample");
  std::printf("page test: %s\n", shown.dump().c_str());
  EXPECT_TRUE(r["errors"].empty()) << r["errors"].dump();
  EXPECT_TRUE(r["first_render_ok"].get<bool>());
  ASSERT_TRUE(r["moved_ok"].get<bool>());
  // The cursor moved from the first frame to the middle one: the footage
  // drawn is that frame's proxy in both cameras, and the mesh moved.
  const int b = 1 + kFrames / 2;
  EXPECT_EQ(r["footage_sources"], nlohmann::json({fmt::format("cam0/{:06d}.jpg", b), fmt::format("cam1/{:06d}.jpg", b)}));
  EXPECT_GT(r["mesh_max_move_mm"].get<double>(), 0.01);
  // The mesh the page drew is the solve's, within the chunks' rounding (at
  // most 1 um: docs/formats.md, "Review page") and float32's.
  const MeshSequence solved = ReadMeshSequence(work / "solve" / "mesh.pc2");
  const nlohmann::json& sample = r["mesh_sample"];
  ASSERT_EQ(sample["frame"].get<int>(), b);
  const MatX3d& mesh_b = solved.frames.at(b - solved.start_frame);
  ASSERT_EQ(sample["vertices"].size(), 50u);
  for (size_t i = 0; i < sample["vertices"].size(); ++i) {
    const int v = sample["vertices"][i].get<int>();
    for (int c = 0; c < 3; ++c) {
      EXPECT_NEAR(sample["positions"][3 * i + c].get<double>(), mesh_b(v, c), 1.01e-3) << "vertex " << v;
    }
  }
  // The scripted rename: cam0's first dot at frame b is given the second
  // dot's name. The CSV it exports, predicted from the tracks.
  const std::vector<Track2d> tracks = ReadTracks2dCsv(d / "tracks_unfixed.csv");
  const std::vector<Track2d> rows = RowsAt(tracks, b, "cam0");
  ASSERT_GE(rows.size(), 2u);
  const std::string expected =
      fmt::format("frame,camera,marker,action,x,y,to\n{},cam0,{},rename,{:.3f},{:.3f},{}\n", b, rows[0].marker,
                  rows[0].pixel.x(), rows[0].pixel.y(), rows[1].marker);
  EXPECT_EQ(r["csv"].get<std::string>(), expected);
  EXPECT_TRUE(r["rename"]["renamed_dot_found"].get<bool>());

  // Applied by hmc run --from track --fixes: at frame b the dot carries
  // its new name, and the workspace keeps the fixes it used.
  WriteFileAtomic(d / "track_fixes.csv", r["csv"].get<std::string>());
  const CliResult rerun = RunHmc(RunArgs() + fmt::format(" --from track --to track --fixes '{}'",
                                                         (d / "track_fixes.csv").string()),
                                 d);
  ASSERT_EQ(rerun.exit_code, 0) << rerun.err;
  EXPECT_EQ(ReadFile(work / "track" / "track_fixes_used.csv"), expected);
  bool renamed = false;
  for (const Track2d& t : RowsAt(ReadTracks2dCsv(work / "track" / "tracks_2d.csv"), b, "cam0")) {
    if (t.marker == rows[1].marker) renamed = (t.pixel - rows[0].pixel).norm() < 1e-3;
  }
  EXPECT_TRUE(renamed);
}

// Issue 48, item 6: every stage's warnings reach the report with their
// markers and frames -- here the triangulation's dropped marker-frames,
// against triangulation.csv read independently -- and no stage row of the
// report is empty.
TEST_F(ReviewTest, TheReportListsEveryDroppedMarkerFrameAndNoEmptyStageRow) {
  const fs::path work = *dir_ / "work";
  std::map<std::string, std::vector<int>> dropped;  // "marker status" -> frames
  bool header = true;
  for (const std::string& line : [&] {
         std::vector<std::string> lines;
         std::string text = ReadFile(work / "triangulate" / "triangulation.csv"), l;
         for (size_t a = 0, b; a < text.size(); a = b + 1) {
           b = text.find('\n', a);
           if (b == std::string::npos) b = text.size();
           lines.push_back(text.substr(a, b - a));
         }
         return lines;
       }()) {
    if (std::exchange(header, false) || line.empty()) continue;
    const size_t c1 = line.find(','), c2 = line.find(',', c1 + 1), c3 = line.find(',', c2 + 1);
    const std::string status = line.substr(c2 + 1, c3 - c2 - 1);
    if (status != "ok") dropped[line.substr(c1 + 1, c2 - c1 - 1) + " " + status].push_back(std::stoi(line.substr(0, c1)));
  }
  std::map<std::string, std::vector<int>> listed;
  const nlohmann::json plots = nlohmann::json::parse(ReadFile(work / "report" / "plots.json"));
  for (const auto& w : plots["warnings"]) {
    if (w["stage"] != "triangulate" || w["markers"].size() != 1) continue;
    const std::string text = w["text"].get<std::string>();
    const size_t open = text.find('('), close = text.find(')');
    listed[w["markers"][0].get<std::string>() + " " + text.substr(open + 1, close - open - 1)] =
        w["frames"].get<std::vector<int>>();
  }
  EXPECT_EQ(listed, dropped);
  std::printf("%zu marker/reason lines of dropped marker-frames\n", dropped.size());
  EXPECT_FALSE(plots["plots"].empty());
  // Every stage row's summary cell (the fourth) holds something.
  const std::string page = ReadFile(work / "report" / "report.html");
  // Rows "<tr><td>stage</td><td>..</td><td>..</td><td>summary</td></tr>".
  int rows = 0;
  for (size_t at = 0; (at = page.find("<tr><td>", at)) != std::string::npos;) {
    const size_t end = page.find("</td></tr>", at);
    if (end == std::string::npos) break;
    std::vector<std::string> cells;
    size_t cell = at + 8;
    for (int i = 0; i < 3; ++i) {
      const size_t next = page.find("</td><td>", cell);
      if (next == std::string::npos || next > end) break;
      cells.push_back(page.substr(cell, next - cell));
      cell = next + 9;
    }
    cells.push_back(page.substr(cell, end - cell));
    at = end;
    const bool stage = cells.size() == 4 && !cells[0].empty() &&
                       cells[0].find_first_not_of("abcdefghijklmnopqrstuvwxyz") == std::string::npos &&
                       cells[1].find('<') == std::string::npos &&
                       cells[2].find('<') == std::string::npos;
    if (!stage) continue;
    ++rows;
    EXPECT_FALSE(cells[3].empty()) << "empty row: " << cells[0];
  }
  EXPECT_EQ(rows, 6);  // calibrate .. solve
}

// `absent` hides a marker in one camera from its frame on; one `rename` at
// a later frame names its dot again, and the tracker follows it from there:
// the marker's rows come back on every later frame, where they were.
TEST_F(ReviewTest, AnAbsentMarkerRenamedOnOneFrameIsTrackedOnTheFramesAfter) {
  const fs::path& d = *dir_;
  const fs::path work = d / "work";
  const std::vector<Track2d> before = ReadTracks2dCsv(d / "tracks_unfixed.csv");
  // A marker named in cam0 on every frame.
  std::map<std::string, int> count;
  for (const Track2d& t : before) count[t.camera + "/" + t.marker] += 1;
  std::string marker;
  for (const Track2d& t : before) {
    if (t.camera == "cam0" && count["cam0/" + t.marker] == kFrames) {
      marker = t.marker;
      break;
    }
  }
  ASSERT_FALSE(marker.empty());
  std::map<int, Vec2> where;
  for (const Track2d& t : before) {
    if (t.camera == "cam0" && t.marker == marker) where[t.frame] = t.pixel;
  }
  const fs::path fixes = d / "absent_fixes.csv";
  WriteFileAtomic(fixes, fmt::format("frame,camera,marker,action,x,y,to\n2,cam0,{},absent,,,\n"
                                     "4,cam0,,rename,{:.3f},{:.3f},{}\n",
                                     marker, where[4].x(), where[4].y(), marker));
  const fs::path out = d / "fixed" / "tracks_2d.csv";
  const std::string track = fmt::format("track --shot '{}' --calibration '{}' --actor '{}' --out '{}' --fixes '{}'",
                                        (d / "shot").string(), (work / "calibrate" / "calibration.yaml").string(),
                                        (d / "actor").string(), out.string(), fixes.string());
  const CliResult r = RunHmc(track, d);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::map<int, Vec2> after;
  for (const Track2d& t : ReadTracks2dCsv(out)) {
    if (t.camera == "cam0" && t.marker == marker) after[t.frame] = t.pixel;
  }
  for (int f = 1; f <= kFrames; ++f) {
    if (f == 2 || f == 3) {
      EXPECT_EQ(after.count(f), 0u) << "absent at frame " << f;
    } else {
      ASSERT_EQ(after.count(f), 1u) << "not named at frame " << f;
      EXPECT_LT((after[f] - where[f]).norm(), 1e-3) << "frame " << f;
    }
  }
  const nlohmann::json summary = nlohmann::json::parse(ReadFile(d / "fixed" / "summary.json"));
  EXPECT_EQ(summary["fixes"]["applied"].get<int>(), 2);

  // A bad fixes file is refused naming the file and the line.
  WriteFileAtomic(fixes, "frame,camera,marker,action,x,y,to\n3,cam0,nose_tip_zz,rename,,,brow_l_01\n");
  const CliResult bad = RunHmc(track, d);
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.err.find("absent_fixes.csv:2"), std::string::npos) << bad.err;
  EXPECT_NE(bad.err.find("nose_tip_zz"), std::string::npos) << bad.err;
}

// `unname` takes the name off a dot from its frame on: the tracker follows
// the dot and names it no more (left as it was, the tracker would re-acquire
// the marker on it the next frames) until a later fix names it; the other
// markers' rows stay.
TEST_F(ReviewTest, UnnamedDotsStayUnnamedUntilAFixNamesThem) {
  const fs::path& d = *dir_;
  const std::vector<Track2d> before = ReadTracks2dCsv(d / "tracks_unfixed.csv");
  std::map<std::string, int> count;
  for (const Track2d& t : before) count[t.camera + "/" + t.marker] += 1;
  // Up to 8 markers named in cam0 on every frame, their dots well apart
  // from the others.
  std::vector<std::string> markers;
  for (const Track2d& t : RowsAt(before, 1, "cam0")) {
    if (count["cam0/" + t.marker] != kFrames || markers.size() == 8) continue;
    double nearest = 1e9;
    for (const Track2d& o : RowsAt(before, 1, "cam0")) {
      if (o.marker != t.marker) nearest = std::min(nearest, (o.pixel - t.pixel).norm());
    }
    if (nearest > 15) markers.push_back(t.marker);
  }
  ASSERT_GE(markers.size(), 4u);
  std::map<std::string, std::map<int, Vec2>> where;
  for (const Track2d& t : before) {
    if (t.camera == "cam0") where[t.marker][t.frame] = t.pixel;
  }
  std::string csv = "frame,camera,marker,action,x,y,to\n";
  for (const std::string& m : markers) {
    csv += fmt::format("2,cam0,{},unname,,,\n5,cam0,,rename,{:.3f},{:.3f},{}\n", m, where[m][5].x(),
                       where[m][5].y(), m);
  }
  const fs::path fixes = d / "unname_fixes.csv";
  WriteFileAtomic(fixes, csv);
  const fs::path out = d / "unnamed" / "tracks_2d.csv";
  const CliResult r = RunHmc(
      fmt::format("track --shot '{}' --calibration '{}' --actor '{}' --out '{}' --fixes '{}'",
                  (d / "shot").string(), (d / "work" / "calibrate" / "calibration.yaml").string(),
                  (d / "actor").string(), out.string(), fixes.string()),
      d);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::vector<Track2d> after = ReadTracks2dCsv(out);
  for (int f = 1; f <= kFrames; ++f) {
    const bool barred = f >= 2 && f < 5;
    for (const std::string& m : markers) {
      bool named = false;
      for (const Track2d& t : RowsAt(after, f, "cam0")) {
        if ((t.pixel - where[m][f]).norm() < 1e-3) {
          named = true;
          EXPECT_EQ(t.marker, m) << "frame " << f;
        }
      }
      EXPECT_EQ(named, !barred) << m << "'s dot at frame " << f;
    }
  }
}

}  // namespace
}  // namespace hmc
