// End to end: `hmc synth shot` (small actor, half-size images, a few frames)
// then `hmc track`, scored against the shot's dots_2d.csv read
// independently (tracking/track_eval.h); corrupt, hidden and wrong inputs.
// The full-size measurement (3 seeds, default and hard presets, offset
// head, small dots) is scripts/measure_tracking (docs/tracking.md).
#include <algorithm>
#include <filesystem>
#include <functional>
#include <map>
#include <set>
#include <sstream>
#include <string>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "core/file_util.h"
#include "core/frame_data.h"
#include "core/tracks_2d.h"
#include "tests/cli_runner.h"
#include "tests/small_actor.h"
#include "tracking/track_eval.h"

namespace hmc {
namespace {

namespace fs = std::filesystem;

// Half the default image and focal length: the face and its dots image at
// half size (dots ~4 px), so a frame renders in a fraction of the time.
constexpr const char* kShotFlags =
    "--rig.width 640 --rig.height 512 --rig.focal_px 350 --contact_frames 0 --video png "
    "--threads 2";

class TrackTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = FreshTestDir("hmc_track_test", 0);
    const CliResult actor =
        RunHmc(fmt::format("actor synth --out '{}' --grid_u 64 --grid_v 52", (dir_ / "actor").string()),
               dir_);
    ASSERT_EQ(actor.exit_code, 0) << actor.err;
  }
  static void TearDownTestSuite() { fs::remove_all(dir_); }

  static fs::path Shot(const std::string& name, int seed, int frames, const std::string& extra = "") {
    const fs::path out = dir_ / name;
    if (fs::exists(out / "dots_2d.csv")) return out;
    const CliResult r = RunHmc(fmt::format("synth shot --actor '{}' --out '{}' --frames {} --seed {} {} {}",
                                           (dir_ / "actor").string(), out.string(), frames, seed,
                                           kShotFlags, extra),
                               dir_);
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return out;
  }
  static CliResult Track(const fs::path& shot, const fs::path& out, const std::string& extra = "") {
    return RunHmc(fmt::format("track --shot '{}' --calibration '{}' --actor '{}' --out '{}' {}",
                              shot.string(), (shot / "calibration.yaml").string(),
                              (dir_ / "actor").string(), out.string(), extra),
                  dir_);
  }
  static fs::path dir_;
};
fs::path TrackTest::dir_;

// Invariants of any tracks_2d.csv: one row per (frame, camera, marker) (the
// reader enforces it), never two names on one dot.
void ExpectNoDotNamedTwice(const std::vector<Track2d>& tracks) {
  std::map<std::pair<int, std::string>, std::vector<Vec2>> by_view;
  for (const Track2d& t : tracks) by_view[{t.frame, t.camera}].push_back(t.pixel);
  for (const auto& [view, pixels] : by_view) {
    for (size_t i = 0; i < pixels.size(); ++i) {
      for (size_t j = i + 1; j < pixels.size(); ++j) {
        ASSERT_GT((pixels[i] - pixels[j]).norm(), 0.5) << "frame " << view.first << " " << view.second;
      }
    }
  }
}

TEST_F(TrackTest, FullDotsAreAccurateAndHiddenDotsUnreportedOnSeveralSeeds) {
  for (int seed = 1; seed <= 3; ++seed) {
    const fs::path shot = Shot(fmt::format("shot{}", seed), seed, 6);
    const fs::path out = dir_ / fmt::format("track{}", seed) / "tracks_2d.csv";
    const CliResult r = Track(shot, out, fmt::format("--diagnostics '{}'", (out.parent_path() / "d.json").string()));
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const std::vector<Track2d> tracks = ReadTracks2dCsv(out);
    ExpectNoDotNamedTwice(tracks);
    const TrackScore s = ScoreTracks(tracks, ReadDots2dCsv(shot / "dots_2d.csv"));
    RecordProperty(fmt::format("seed{}", seed), s.BriefReport());
    std::printf("seed %d: %s\n", seed, s.BriefReport().c_str());
    std::printf("seed %d: %s\n", seed, s.WholeReport().c_str());
    // Issue targets met at this size (docs/tracking.md has the full-size figures).
    EXPECT_LE(s.median_px, 0.05) << "seed " << seed;
    EXPECT_LE(s.p95_px, 0.15) << "seed " << seed;
    EXPECT_LE(s.HiddenFraction(), 0.005) << "seed " << seed;
    // Most full dots are named and almost no row is wrong (the targets
    // 99.5 % and 0 are not met yet: docs/tracking.md, "What fails").
    EXPECT_GE(s.FullRecall(), 0.9) << "seed " << seed;
    EXPECT_LE(s.WrongFraction(), 0.01) << "seed " << seed;
    // Whole dots seen edge-on (issue 44; dots ~4 px here, so a dot at view
    // cosine 0.2 is under a pixel wide): those at 0.3-0.4 are named as
    // often as face-on ones, and those down to 0.15 are centred as well as
    // full ones; the 0.15-0.3 bin (65-70 % named here with the matched
    // filter of the predicted ellipse, 63-64 % with the centroid over it,
    // 53-56 % before the search for expected dots, 44-48 % before the
    // detector's level against the closed skin) misses the 99 %
    // (docs/tracking.md); from 0.15 on 91.7-93.0 %, 0.3-0.4 96.9-97.4 %.
    ASSERT_TRUE(s.has_whole);
    EXPECT_GE(s.whole_bins[1].Recall(), 0.63) << "seed " << seed;
    EXPECT_GE(s.whole_bins[2].Recall(), 0.95) << "seed " << seed;
    EXPECT_GE(s.whole_from_015.Recall(), 0.9) << "seed " << seed;
    EXPECT_LE(s.whole_from_015.median_px, 0.05) << "seed " << seed;
    const nlohmann::json diag = nlohmann::json::parse(ReadFile(out.parent_path() / "d.json"));
    EXPECT_EQ(diag["frames"].size(), 6u);
    EXPECT_TRUE(diag["labelling"]["ok"].get<bool>());
    // Every marker is painted: those never found are hidden or grazing, and
    // no dot is reported missing (issue 45: the warning fired on clean shots).
    EXPECT_TRUE(diag["missing_dots"].empty()) << "seed " << seed << ": " << diag["missing_dots"];
    EXPECT_EQ(r.err.find("markers never found"), std::string::npos) << r.err;
  }
}

TEST_F(TrackTest, LabelsAHeadOffsetFifteenMillimetresAndTenDegrees) {
  for (int seed = 4; seed <= 5; ++seed) {
    const fs::path shot = Shot(fmt::format("offset{}", seed), seed, 2,
                               "--head_offset_mm 15 --head_offset_deg 10");
    const fs::path out = dir_ / fmt::format("track_offset{}", seed) / "tracks_2d.csv";
    const CliResult r = Track(shot, out);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const TrackScore s = ScoreTracks(ReadTracks2dCsv(out), ReadDots2dCsv(shot / "dots_2d.csv"));
    std::printf("offset seed %d: %s\n", seed, s.BriefReport().c_str());
    EXPECT_GE(s.FullRecall(), 0.9) << "seed " << seed;
    EXPECT_LE(s.WrongFraction(), 0.01) << "seed " << seed;
  }
}

// A take that starts with the mouth open: the labelling finds the jaw pose
// with the head's (the actor's jaw rig, docs/tracking.md), and names the
// chin and lip dots as well as at rest. Before the jaw search the chin dots
// of such a shot took their neighbours' names for the whole shot.
TEST_F(TrackTest, LabelsAReferenceFrameWithTheJawOpen) {
  int open = 0;
  for (int seed = 6; seed <= 8; ++seed) {
    const fs::path shot = Shot(fmt::format("jaw{}", seed), seed, 2, "--jaw_activity 0.8");
    const fs::path out = dir_ / fmt::format("track_jaw{}", seed) / "tracks_2d.csv";
    const fs::path diag_path = out.parent_path() / "d.json";
    const CliResult r = Track(shot, out, fmt::format("--diagnostics '{}'", diag_path.string()));
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const JawPose truth = ReadJawCsv(shot / "jaw.csv").at(0).pose;
    const nlohmann::json jaw = nlohmann::json::parse(ReadFile(diag_path))["labelling"]["jaw"];
    std::printf("jaw seed %d: true open %.2f lateral %.2f protrude %.2f, found %s\n", seed,
                truth.open_deg, truth.lateral_deg, truth.protrude_mm, jaw.dump().c_str());
    open += truth.open_deg >= 5;
    EXPECT_NEAR(jaw["open_deg"].get<double>(), truth.open_deg, 1.0) << "seed " << seed;
    EXPECT_NEAR(jaw["lateral_deg"].get<double>(), truth.lateral_deg, 1.5) << "seed " << seed;
    const TrackScore s = ScoreTracks(ReadTracks2dCsv(out), ReadDots2dCsv(shot / "dots_2d.csv"));
    std::printf("jaw seed %d: %s\n", seed, s.BriefReport().c_str());
    EXPECT_GE(s.FullRecall(), 0.9) << "seed " << seed;
    EXPECT_LE(s.WrongFraction(), 0.01) << "seed " << seed;
  }
  EXPECT_GE(open, 1) << "no seed opened the jaw 5 degrees at frame 1: the test tests nothing";
}

// Shots whose set is drawn from the seed (`--vary.on true`, as every
// configs/synth_shot_*.yaml preset; docs/footage.md, "Varied sets"): two
// seeds draw different sets (exposure, its drift, vignetting, skin,
// specularity, dot size and darkness, blur, noise), and the tracker names
// and centres their dots as on the default set (the same bars as
// FullDotsAreAccurateAndHiddenDotsUnreportedOnSeveralSeeds).
// The search for expected dots (docs/tracking.md, "Searching for an
// expected dot") against ground truth: on the same shots it names more of
// the whole dots seen from view cosine 0.15 on than the tracker without
// it, centres them as well, and names almost no dot wrongly.
TEST_F(TrackTest, SearchingForExpectedDotsNamesMoreWholeDots) {
  for (int seed = 1; seed <= 3; ++seed) {
    const fs::path shot = Shot(fmt::format("shot{}", seed), seed, 6);
    TrackScore score[2];
    for (int search = 0; search < 2; ++search) {
      const fs::path out = dir_ / fmt::format("search{}_{}", seed, search) / "tracks_2d.csv";
      const CliResult r = Track(shot, out, search ? "" : "--track.search_gate 0");
      ASSERT_EQ(r.exit_code, 0) << r.err;
      const std::vector<Track2d> tracks = ReadTracks2dCsv(out);
      ExpectNoDotNamedTwice(tracks);
      score[search] = ScoreTracks(tracks, ReadDots2dCsv(shot / "dots_2d.csv"));
      std::printf("seed %d search %d: %s\n%s\n", seed, search, score[search].BriefReport().c_str(),
                  score[search].WholeReport().c_str());
    }
    const WholeDotBin& off = score[0].whole_from_015;
    const WholeDotBin& on = score[1].whole_from_015;
    EXPECT_GT(on.named, off.named) << "seed " << seed;
    EXPECT_LE(on.median_px, 0.05) << "seed " << seed;
    EXPECT_LE(score[1].WrongFraction(), 0.01) << "seed " << seed;
    EXPECT_LE(score[1].HiddenFraction(), 0.005) << "seed " << seed;
  }
}

TEST_F(TrackTest, TracksShotsOfVariedSets) {
  std::set<std::string> sets;
  for (int seed = 11; seed <= 12; ++seed) {
    const fs::path shot = Shot(fmt::format("varied{}", seed), seed, 4, "--vary.on true");
    ASSERT_TRUE(fs::exists(shot / "variation.yaml"));
    const std::string set = ReadFile(shot / "variation.yaml");
    sets.insert(set.substr(set.find("render:")));
    const fs::path out = dir_ / fmt::format("track_varied{}", seed) / "tracks_2d.csv";
    const CliResult r = Track(shot, out);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const TrackScore s = ScoreTracks(ReadTracks2dCsv(out), ReadDots2dCsv(shot / "dots_2d.csv"));
    std::printf("varied seed %d: %s\n%s", seed, s.BriefReport().c_str(),
                set.c_str());
    EXPECT_LE(s.median_px, 0.05) << "seed " << seed;
    EXPECT_LE(s.p95_px, 0.15) << "seed " << seed;
    EXPECT_GE(s.FullRecall(), 0.9) << "seed " << seed;
    EXPECT_LE(s.WrongFraction(), 0.01) << "seed " << seed;
  }
  EXPECT_EQ(sets.size(), 2u) << "two seeds drew the same set";
}

// Paints skin over one named dot in frames 3 and 4 of cam0: it has no row
// there, and is named again (at the clean run's place) from frame 5 on.
TEST_F(TrackTest, AHiddenDotIsNotReportedAndIsReacquired) {
  const fs::path clean_shot = Shot("shot1", 1, 6);
  const fs::path clean = dir_ / "track1" / "tracks_2d.csv";
  if (!fs::exists(clean)) {
    ASSERT_EQ(Track(clean_shot, clean).exit_code, 0);
  }
  const std::vector<Track2d> reference = ReadTracks2dCsv(clean);
  // A marker named in cam0 in every frame.
  std::map<std::string, std::map<int, Vec2>> by_marker;
  for (const Track2d& t : reference) {
    if (t.camera == "cam0") by_marker[t.marker][t.frame] = t.pixel;
  }
  std::string marker;
  for (const auto& [name, frames] : by_marker) {
    if (frames.size() == 6 && name.rfind("cheek", 0) == 0) {
      marker = name;
      break;
    }
  }
  ASSERT_FALSE(marker.empty());
  const fs::path shot = dir_ / "hidden";
  fs::remove_all(shot);
  fs::create_directories(shot);
  fs::copy(clean_shot, shot, fs::copy_options::recursive);
  for (int frame : {3, 4}) {
    const fs::path png = shot / "cam0" / fmt::format("frame_{:06d}.png", frame);
    cv::Mat image = cv::imread(png.string(), cv::IMREAD_GRAYSCALE);
    const Vec2 p = by_marker[marker][frame];
    const cv::Point centre(static_cast<int>(std::lround(p.x())), static_cast<int>(std::lround(p.y())));
    // Skin level: the median of a ring around the dot.
    std::vector<uint8_t> ring;
    for (int a = 0; a < 32; ++a) {
      const int x = centre.x + static_cast<int>(std::lround(9 * std::cos(a * M_PI / 16)));
      const int y = centre.y + static_cast<int>(std::lround(9 * std::sin(a * M_PI / 16)));
      ring.push_back(image.at<uint8_t>(y, x));
    }
    std::nth_element(ring.begin(), ring.begin() + 16, ring.end());
    cv::circle(image, centre, 5, cv::Scalar(ring[16]), -1);
    ASSERT_TRUE(cv::imwrite(png.string(), image));
  }
  const fs::path out = dir_ / "track_hidden" / "tracks_2d.csv";
  ASSERT_EQ(Track(shot, out).exit_code, 0);
  std::map<int, Vec2> rows;
  for (const Track2d& t : ReadTracks2dCsv(out)) {
    if (t.camera == "cam0" && t.marker == marker) rows[t.frame] = t.pixel;
  }
  EXPECT_EQ(rows.count(3), 0u) << marker;
  EXPECT_EQ(rows.count(4), 0u) << marker;
  for (int frame : {5, 6}) {
    ASSERT_EQ(rows.count(frame), 1u) << marker << " not re-acquired at frame " << frame;
    EXPECT_LT((rows[frame] - by_marker[marker][frame]).norm(), 1e-6) << marker;
  }
}

TEST_F(TrackTest, ACorruptFrameIsSkippedAndTrackingGoesOn) {
  const fs::path clean_shot = Shot("shot2", 2, 6);
  const fs::path shot = dir_ / "corrupt";
  fs::remove_all(shot);
  fs::create_directories(shot);
  fs::copy(clean_shot, shot, fs::copy_options::recursive);
  WriteFileAtomic(shot / "cam1" / "frame_000003.png", std::string("not a png"));
  const fs::path out = dir_ / "track_corrupt" / "tracks_2d.csv";
  const fs::path diag_path = out.parent_path() / "d.json";
  const CliResult r = Track(shot, out, fmt::format("--diagnostics '{}'", diag_path.string()));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json diag = nlohmann::json::parse(ReadFile(diag_path));
  bool skipped = false;
  for (const auto& f : diag["frames"]) {
    if (f["frame"] == 3) skipped = f["cameras"]["cam1"]["skipped"].get<bool>();
  }
  EXPECT_TRUE(skipped);
  std::map<int, int> cam1_rows, cam0_rows;
  for (const Track2d& t : ReadTracks2dCsv(out)) ++(t.camera == "cam1" ? cam1_rows : cam0_rows)[t.frame];
  EXPECT_EQ(cam1_rows.count(3), 0u);
  EXPECT_GT(cam0_rows[3], 20);
  // Frames after the broken one are tracked as well as before it.
  for (int frame : {4, 5, 6}) EXPECT_GE(cam1_rows[frame], 0.9 * cam1_rows[2]) << "frame " << frame;
}

// A copy of a PNG shot's frames (and its calibration.yaml), each frame's
// image passed through `change(image, frame)`.
void CopyShotFrames(const fs::path& shot, const fs::path& copy,
                    const std::function<cv::Mat(const cv::Mat&, int)>& change) {
  fs::remove_all(copy);
  fs::create_directories(copy);
  fs::copy_file(shot / "calibration.yaml", copy / "calibration.yaml");
  for (const char* camera : {"cam0", "cam1"}) {
    fs::create_directories(copy / camera);
    for (const auto& entry : fs::directory_iterator(shot / camera)) {
      const cv::Mat image = cv::imread(entry.path().string(), cv::IMREAD_UNCHANGED);
      const std::string stem = entry.path().stem().string();
      const int frame = std::stoi(stem.substr(stem.size() - 6));
      ASSERT_TRUE(cv::imwrite((copy / camera / entry.path().filename()).string(),
                              change(image, frame)));
    }
  }
}

// sRGB-encoded PNGs (which say so with an sRGB chunk) are linearised before
// the detector (footage.transfer auto): tracked as well as the same shot
// rendered with linear values. Read as linear values (the reading before
// footage.transfer, and --footage.transfer linear now), the lifted dark
// skin texture gives many more detections and worse centres.
TEST_F(TrackTest, SrgbFootageIsLinearisedBeforeTheDetector) {
  const int seed = 7;
  const fs::path linear_shot = Shot("shot_linear7", seed, 4);
  const fs::path srgb_shot = Shot("shot_srgb7", seed, 4, "--render.transfer srgb");
  struct Result {
    TrackScore score;
    nlohmann::json summary;
  };
  auto track = [&](const fs::path& shot, const std::string& name, const std::string& extra) {
    const fs::path out = dir_ / name / "tracks_2d.csv";
    const CliResult r = Track(shot, out, extra);
    EXPECT_EQ(r.exit_code, 0) << r.err;
    Result result;
    result.score = ScoreTracks(ReadTracks2dCsv(out), ReadDots2dCsv(shot / "dots_2d.csv"));
    result.summary = nlohmann::json::parse(ReadFile(out.parent_path() / "summary.json"));
    std::printf("%s: %s; %.1f detections per view\n", name.c_str(),
                result.score.BriefReport().c_str(),
                result.summary["summary"]["mean_detections"].get<double>());
    return result;
  };
  const Result linear = track(linear_shot, "track_linear7", "");
  const Result srgb = track(srgb_shot, "track_srgb7", "");
  const Result as_stored = track(srgb_shot, "track_srgb7_as_stored", "--footage.transfer linear");
  EXPECT_EQ(linear.summary["transfer"]["cam0"]["read_as"], "linear");
  EXPECT_EQ(srgb.summary["transfer"]["cam0"]["read_as"], "srgb");
  EXPECT_EQ(srgb.summary["transfer"]["cam1"]["read_as"], "srgb");
  EXPECT_EQ(as_stored.summary["transfer"]["cam0"]["read_as"], "linear");
  const double linear_detections = linear.summary["summary"]["mean_detections"].get<double>();
  const double srgb_detections = srgb.summary["summary"]["mean_detections"].get<double>();
  const double stored_detections = as_stored.summary["summary"]["mean_detections"].get<double>();
  EXPECT_NEAR(srgb_detections, linear_detections, 0.1 * linear_detections);
  EXPECT_GT(stored_detections, 1.3 * linear_detections);
  EXPECT_GE(srgb.score.FullRecall(), linear.score.FullRecall() - 0.02);
  EXPECT_LE(srgb.score.WrongFraction(), linear.score.WrongFraction() + 0.002);
  EXPECT_LE(srgb.score.median_px, linear.score.median_px + 0.005);
  EXPECT_LE(srgb.score.p95_px, linear.score.p95_px + 0.02);
}

// 16-bit and colour frames (grey values in three equal channels) give the
// tracks of the 8-bit grey original: the reader turns them into the same
// grey levels (16-bit = 8-bit x 257), so every row is there, at the same
// centre to float rounding (a pixel on a threshold's edge).
TEST_F(TrackTest, SixteenBitAndColourFramesGiveTheTracksOfTheEightBitGrey) {
  const fs::path shot = Shot("shot_depths", 8, 3);
  const fs::path out8 = dir_ / "track_depths_8" / "tracks_2d.csv";
  ASSERT_EQ(Track(shot, out8).exit_code, 0);
  const std::vector<Track2d> grey8 = ReadTracks2dCsv(out8);
  ASSERT_GT(grey8.size(), 100u);
  for (const std::string kind : {"grey16", "colour8", "colour16"}) {
    const fs::path copy = dir_ / ("shot_depths_" + kind);
    CopyShotFrames(shot, copy, [&](const cv::Mat& grey8_image, int) {
      EXPECT_EQ(grey8_image.type(), CV_8UC1);
      cv::Mat image = grey8_image;
      if (kind != "grey16") cv::cvtColor(image, image, cv::COLOR_GRAY2BGR);
      if (kind != "colour8") image.convertTo(image, CV_16U, 257);
      return image;
    });
    const fs::path out = dir_ / ("track_depths_" + kind) / "tracks_2d.csv";
    const CliResult r = Track(copy, out);
    ASSERT_EQ(r.exit_code, 0) << kind << ": " << r.err;
    const std::vector<Track2d> tracks = ReadTracks2dCsv(out);
    ASSERT_EQ(tracks.size(), grey8.size()) << kind;
    for (size_t i = 0; i < tracks.size(); ++i) {
      ASSERT_EQ(tracks[i].frame, grey8[i].frame) << kind;
      ASSERT_EQ(tracks[i].camera, grey8[i].camera) << kind;
      ASSERT_EQ(tracks[i].marker, grey8[i].marker) << kind;
      // 16-bit levels / 65535 and 8-bit / 255 round differently in float,
      // which can move a pixel across a threshold: 0.002 px seen.
      EXPECT_LT((tracks[i].pixel - grey8[i].pixel).norm(), 0.01) << kind << " " << tracks[i].marker;
    }
  }
}

// Exposure changing over the shot (an auto-exposure or a light dimming),
// on top of the renderer's vignetting: each frame's values scaled by a
// gain that drifts from 1 to `gain` (darker: 0.45, brighter: 1.5, the
// highlights clipping) and rounded again. The detector's relative
// darkening and the flow's normalised windows take it: the dots are named
// as in the original and their centres as accurate.
TEST_F(TrackTest, ExposureDriftingOverTheShotIsTracked) {
  const fs::path shot = Shot("shot_exposure", 9, 6);
  const std::vector<Dot2dTruth> truth = ReadDots2dCsv(shot / "dots_2d.csv");
  const fs::path out0 = dir_ / "track_exposure" / "tracks_2d.csv";
  ASSERT_EQ(Track(shot, out0).exit_code, 0);
  const TrackScore original = ScoreTracks(ReadTracks2dCsv(out0), truth);
  std::printf("original: %s\n", original.BriefReport().c_str());
  for (const double gain : {0.45, 1.5}) {
    const fs::path copy = dir_ / fmt::format("shot_exposure_{}", gain);
    CopyShotFrames(shot, copy, [&](const cv::Mat& image, int frame) {
      // Frame 1 (the reference) at 1, the last frame at `gain`.
      const double g = 1 + (gain - 1) * (frame - 1) / 5.0;
      cv::Mat scaled;
      image.convertTo(scaled, CV_8U, g);  // rounded, saturated at 255
      return scaled;
    });
    const fs::path out = dir_ / fmt::format("track_exposure_{}", gain) / "tracks_2d.csv";
    const CliResult r = Track(copy, out);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const TrackScore s = ScoreTracks(ReadTracks2dCsv(out), truth);
    std::printf("gain 1 -> %.2f: %s\n", gain, s.BriefReport().c_str());
    EXPECT_GE(s.FullRecall(), original.FullRecall() - 0.02) << gain;
    EXPECT_LE(s.WrongFraction(), original.WrongFraction() + 0.002) << gain;
    EXPECT_LE(s.median_px, original.median_px + 0.01) << gain;
    EXPECT_LE(s.p95_px, original.p95_px + 0.03) << gain;
  }
}

TEST_F(TrackTest, WrongSizeOrUnreadableFootageIsRefusedWithTheFileNamed) {
  const fs::path shot = Shot("shot3", 3, 6);
  const fs::path junk = dir_ / "junk.mkv";
  WriteFileAtomic(junk, std::string("this is not a video"));
  CliResult r = Track(shot, dir_ / "refused" / "tracks_2d.csv", fmt::format("--cam0 '{}'", junk.string()));
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("junk.mkv"), std::string::npos) << r.err;
  // cam1 from a shot of another size.
  const fs::path small = dir_ / "small_cam1";
  fs::create_directories(small);
  for (int frame = 1; frame <= 6; ++frame) {
    cv::Mat image = cv::imread((shot / "cam1" / fmt::format("frame_{:06d}.png", frame)).string(),
                               cv::IMREAD_GRAYSCALE);
    cv::Mat half;
    cv::resize(image, half, cv::Size(320, 256));
    ASSERT_TRUE(cv::imwrite((small / fmt::format("frame_{:06d}.png", frame)).string(), half));
  }
  r = Track(shot, dir_ / "refused" / "tracks_2d.csv", fmt::format("--cam1 '{}'", small.string()));
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("small_cam1"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir_ / "refused" / "tracks_2d.csv"));
}

// Issue 45, item 11: markers of the actor that are never found over the
// shot (30 not painted: the shot is rendered with an actor without them)
// are reported by name (before: wrong names rose, without a word).
// Dots rubbed off mid-take (`--paint_lost_at 4:10`; docs/tracking.md, "Dots
// lost mid-take"), two seeds: a dot reported lost is one of those rubbed
// off, from their frame (or the next two: the dot must be missing where it
// should be seen), and to the end; no name of a rubbed-off dot moves to
// another marker's dot.
TEST_F(TrackTest, ADotLostMidTakeIsReportedFromItsFrameAndNotRenamed) {
  constexpr int kLostFrame = 4;
  for (int seed : {5, 6}) {
    const fs::path shot = Shot(fmt::format("lost{}", seed), seed, 9,
                               fmt::format("--paint_lost_at {}:10", kLostFrame));
    const fs::path out = dir_ / fmt::format("track_lost{}", seed) / "tracks_2d.csv";
    const CliResult r = Track(shot, out);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    // The shot's truth: "# lost from frame F: NAME NAME ..." in painted_markers.csv.
    const std::string painted = ReadFile(shot / "painted_markers.csv");
    const std::string tag = fmt::format("# lost from frame {}: ", kLostFrame);
    const size_t at = painted.find(tag);
    ASSERT_NE(at, std::string::npos) << painted.substr(0, 300);
    std::set<std::string> lost;
    std::istringstream names(painted.substr(at + tag.size(), painted.find('\n', at) - at - tag.size()));
    for (std::string name; names >> name;) lost.insert(name);
    ASSERT_EQ(lost.size(), 10u);
    const nlohmann::json summary = nlohmann::json::parse(ReadFile(out.parent_path() / "summary.json"));
    int reported = 0;
    for (const nlohmann::json& l : summary["lost_dots"]) {
      const std::string marker = l["marker"];
      EXPECT_EQ(lost.count(marker), 1u) << "seed " << seed << ": " << marker << " reported lost";
      EXPECT_GE(l["from_frame"].get<int>(), kLostFrame) << marker;
      EXPECT_LE(l["from_frame"].get<int>(), kLostFrame + 2) << marker;
      EXPECT_TRUE(l["back_frame"].is_null()) << marker;
      ++reported;
    }
    // Measured: 4 and 3 of the 10 (the others face a camera at a grazing
    // angle, or are left unnamed before they are rubbed off).
    EXPECT_GE(reported, 2) << "seed " << seed << ": " << summary["lost_dots"].dump();
    if (reported > 0) {
      EXPECT_NE(r.err.find("dots lost mid-take"), std::string::npos) << r.err;
    }
    // Every row of a rubbed-off marker after it is gone: on no other
    // marker's dot.
    std::map<std::pair<int, std::string>, std::vector<Vec2>> dots;  // (frame, camera) -> visible dots
    for (const Dot2dTruth& d : ReadDots2dCsv(shot / "dots_2d.csv")) {
      if (d.visible) dots[{d.frame, d.camera}].push_back(d.pixel);
    }
    for (const Track2d& t : ReadTracks2dCsv(out)) {
      if (t.frame < kLostFrame || !lost.count(t.marker)) continue;
      for (const Vec2& p : dots[{t.frame, t.camera}]) {
        EXPECT_GT((t.pixel - p).norm(), 2.0)
            << "seed " << seed << ": " << t.marker << " on another dot at frame " << t.frame << " " << t.camera;
      }
    }
  }
}

TEST_F(TrackTest, MarkersNeverFoundOverTheShotAreReported) {
  const fs::path fewer = dir_ / "actor_fewer";
  fs::copy(dir_ / "actor", fewer, fs::copy_options::recursive);
  const std::string markers = ReadFile(fewer / "markers.csv");
  std::vector<std::string> lines;
  for (size_t at = 0, end; at < markers.size(); at = end + 1) {
    end = markers.find('\n', at);
    if (end == std::string::npos) end = markers.size();
    lines.push_back(markers.substr(at, end - at));
  }
  // Every third marker row from the 2nd onwards, 30 of them, is not painted.
  std::set<std::string> removed;
  std::string kept;
  int row = 0;
  for (const std::string& line : lines) {
    const bool data = !line.empty() && line[0] != '#' && line.rfind("name,", 0) != 0;
    if (data && row++ % 3 == 1 && removed.size() < 30) {
      removed.insert(line.substr(0, line.find(',')));
      continue;
    }
    if (!line.empty()) kept += line + "\n";
  }
  ASSERT_EQ(removed.size(), 30u);
  WriteFileAtomic(fewer / "markers.csv", kept);
  const fs::path shot = dir_ / "shot_fewer";
  const CliResult synth = RunHmc(
      fmt::format("synth shot --actor '{}' --out '{}' --frames 3 --seed 4 {}", fewer.string(),
                  shot.string(), kShotFlags),
      dir_);
  ASSERT_EQ(synth.exit_code, 0) << synth.err;
  const fs::path out = dir_ / "track_fewer" / "tracks_2d.csv";
  const CliResult r = Track(shot, out);  // with the whole actor
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("markers never found over the shot, their dots missing"),
            std::string::npos)
      << r.err;
  const nlohmann::json summary = nlohmann::json::parse(ReadFile(out.parent_path() / "summary.json"));
  const std::vector<std::string> never = summary["never_found"];
  // Never found: most of the unpainted ones; none of them is in the tracks,
  // and every marker not in the tracks is listed.
  int unpainted = 0;
  for (const std::string& name : never) unpainted += removed.count(name);
  EXPECT_GE(unpainted, 25) << summary["never_found"].dump();
  // Missing dots (warned): only unpainted markers, at least half of them
  // (16 here; not those that face no camera within 60 degrees), the first
  // ones named in the warning.
  const std::vector<std::string> missing = summary["missing_dots"];
  for (const std::string& name : missing) EXPECT_EQ(removed.count(name), 1u) << name;
  EXPECT_GE(missing.size(), 15u) << summary["missing_dots"].dump();
  if (!missing.empty()) {
    EXPECT_NE(r.err.find(missing.front()), std::string::npos) << r.err;
  }
  std::set<std::string> tracked;
  for (const Track2d& t : ReadTracks2dCsv(out)) tracked.insert(t.marker);
  for (const std::string& name : never) EXPECT_EQ(tracked.count(name), 0u) << name;
  std::set<std::string> all;
  for (const std::string& line : lines) {
    if (!line.empty() && line[0] != '#' && line.rfind("name,", 0) != 0) all.insert(line.substr(0, line.find(',')));
  }
  EXPECT_EQ(never.size() + tracked.size(), all.size());
}

TEST_F(TrackTest, UndistortWritesPinholeFramesWithTheTracksDrawn) {
  const fs::path shot = Shot("shot1", 1, 6);
  const fs::path tracks = dir_ / "track1" / "tracks_2d.csv";
  if (!fs::exists(tracks)) {
    ASSERT_EQ(Track(shot, tracks).exit_code, 0);
  }
  const fs::path out = dir_ / "undistorted";
  const CliResult r = RunHmc(fmt::format("undistort --shot '{}' --calibration '{}' --out '{}' --camera cam0 "
                                         "--fov-deg 100 --tracks '{}' --frames 1:2",
                                         shot.string(), (shot / "calibration.yaml").string(),
                                         out.string(), tracks.string()),
                             dir_);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const cv::Mat image = cv::imread((out / "cam0" / "frame_000001.png").string(), cv::IMREAD_COLOR);
  ASSERT_FALSE(image.empty());
  EXPECT_EQ(image.cols, 640);
  EXPECT_EQ(image.rows, 512);
  EXPECT_FALSE(fs::exists(out / "cam1"));
  EXPECT_FALSE(fs::exists(out / "cam0" / "frame_000003.png"));
}

}  // namespace
}  // namespace hmc
