// End to end: `hmc actor synth` (small) then `hmc synth shot` at a small
// image size: the video is lossless (FFV1 decodes to the PNG frames), the
// shot is deterministic by seed, and the ground-truth files agree with each
// other through calibration.yaml.
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include "core/file_util.h"
#include "core/frame_data.h"
#include "synth/helmet_rig.h"

namespace hmc {
namespace {

namespace fs = std::filesystem;

int RunHmc(const std::string& arguments, const fs::path& log) {
  const std::string command = fmt::format("'{}' {} >'{}' 2>&1", HMC_BINARY, arguments, log.string());
  return std::system(command.c_str());
}

class SynthShotTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = fs::temp_directory_path() / fmt::format("hmc_synth_shot_test_{}", ::getpid());
    fs::create_directories(dir_);
    ASSERT_EQ(RunHmc(fmt::format("actor synth --out '{}' --grid_u 128 --grid_v 100",
                                 (dir_ / "actor").string()),
                     dir_ / "actor.log"),
              0)
        << ReadFile(dir_ / "actor.log");
  }
  static void TearDownTestSuite() { fs::remove_all(dir_); }

  static std::string Shot(const std::string& name, const std::string& extra) {
    const fs::path out = dir_ / name;
    const int status =
        RunHmc(fmt::format("synth shot --actor '{}' --out '{}' --frames 5 --rig.width 320 "
                           "--rig.height 256 --rig.focal_px 175 --contact_frames 2 {}",
                           (dir_ / "actor").string(), out.string(), extra),
               dir_ / (name + ".log"));
    EXPECT_EQ(status, 0) << ReadFile(dir_ / (name + ".log"));
    return out.string();
  }

  static fs::path dir_;
};
fs::path SynthShotTest::dir_;

std::vector<cv::Mat> DecodeVideo(const fs::path& path) {
  cv::VideoCapture capture(path.string(), cv::CAP_FFMPEG);
  EXPECT_TRUE(capture.isOpened()) << path;
  std::vector<cv::Mat> frames;
  cv::Mat frame;
  while (capture.read(frame)) {
    cv::Mat grey;
    if (frame.channels() == 3) {
      cv::cvtColor(frame, grey, cv::COLOR_BGR2GRAY);
    } else {
      grey = frame.clone();
    }
    frames.push_back(grey);
  }
  return frames;
}

TEST_F(SynthShotTest, LosslessDeterministicAndConsistent) {
  const fs::path a = Shot("a", "");
  const fs::path b = Shot("b", "");
  const fs::path png = Shot("png", "--video png");
  const fs::path other = Shot("other", "--seed 2");
  for (const char* file : {"calibration.yaml", "dots_2d.csv", "bundles.csv",
                           "bundles_helmet.csv", "head_from_helmet.csv", "jaw.csv",
                           "tags_2d.csv", "truth.pc2", "neutral.obj", "contact_sheet.png"}) {
    ASSERT_TRUE(fs::exists(a / file)) << file;
    EXPECT_EQ(ReadFile(a / file), ReadFile(b / file)) << file << " differs between runs";
  }
  EXPECT_NE(ReadFile(a / "dots_2d.csv"), ReadFile(other / "dots_2d.csv"));
  for (const char* cam : {"cam0", "cam1"}) {
    const std::vector<cv::Mat> video = DecodeVideo(a / (std::string(cam) + ".mkv"));
    const std::vector<cv::Mat> again = DecodeVideo(b / (std::string(cam) + ".mkv"));
    ASSERT_EQ(video.size(), 5u);
    ASSERT_EQ(again.size(), 5u);
    for (int f = 0; f < 5; ++f) {
      const cv::Mat written =
          cv::imread((png / cam / fmt::format("frame_{:06d}.png", f + 1)).string(),
                     cv::IMREAD_UNCHANGED);
      ASSERT_EQ(written.type(), CV_8UC1);
      ASSERT_EQ(video[f].size(), written.size());
      EXPECT_EQ(cv::norm(video[f], written, cv::NORM_INF), 0) << cam << " frame " << f + 1;
      EXPECT_EQ(cv::norm(video[f], again[f], cv::NORM_INF), 0);
      EXPECT_GT(cv::mean(written)[0], 2.0) << "an empty frame";
    }
  }
  // dots_2d.csv is the projection of bundles_helmet.csv through the
  // calibration, and bundles.csv maps to bundles_helmet.csv by
  // head_from_helmet.csv.
  const HelmetRig rig = ReadCalibration(a / "calibration.yaml");
  ASSERT_EQ(rig.cameras.size(), 2u);
  ASSERT_EQ(rig.tags.size(), 4u);
  const std::vector<BundleFrame> helmet = ReadBundlesCsv(a / "bundles_helmet.csv");
  const std::vector<BundleFrame> head = ReadBundlesCsv(a / "bundles.csv");
  ASSERT_EQ(helmet.size(), 5u);
  std::map<int, Rigid3> head_from_helmet;
  for (const PoseFrame& pose : ReadPosesCsv(a / "head_from_helmet.csv")) {
    head_from_helmet[pose.frame] = pose.pose;
  }
  for (size_t f = 0; f < helmet.size(); ++f) {
    for (const auto& [name, p] : helmet[f].bundles) {
      const Vec3 in_head = head_from_helmet.at(helmet[f].frame) * p;
      EXPECT_LT((in_head - head[f].bundles.at(name)).norm(), 1e-5);
    }
  }
  std::istringstream in(ReadFile(a / "dots_2d.csv"));
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "frame,camera,marker,x,y,visible,disc,cx,cy,seen,cos,whole,wcx,wcy");
  int rows = 0, visible = 0, full = 0, cut = 0, grazing_whole = 0;
  while (std::getline(in, line)) {
    std::istringstream row(line);
    std::string frame, cam, marker, x, y, vis, disc, cx, cy, seen, cos, whole, wcx, wcy;
    std::getline(row, frame, ',');
    std::getline(row, cam, ',');
    std::getline(row, marker, ',');
    std::getline(row, x, ',');
    std::getline(row, y, ',');
    std::getline(row, vis, ',');
    std::getline(row, disc, ',');
    std::getline(row, cx, ',');
    std::getline(row, cy, ',');
    std::getline(row, seen, ',');
    std::getline(row, cos, ',');
    std::getline(row, whole, ',');
    std::getline(row, wcx, ',');
    std::getline(row, wcy, ',');
    // How much of the dot is seen, relative to face-on: at least cos 60
    // degrees of a full dot (every sample within 60 degrees of square),
    // less than that of some partial ones (slivers, cut dots).
    const double seen_fraction = std::stod(seen);
    EXPECT_GE(seen_fraction, 0.0) << line;
    EXPECT_LE(seen_fraction, 1.0) << line;
    if (disc == "full") {
      EXPECT_GE(seen_fraction, 0.5 - 1e-3) << line;  // written with 3 decimals
    }
    cut += disc == "partial" && seen_fraction < 0.5;
    // The expected dot centroid exists for fully visible dots only, and lies
    // near the projected marker (the skin's curvature moves it < 1.5 px).
    EXPECT_EQ(cx.empty(), disc != "full") << line;
    if (!cx.empty()) {
      EXPECT_LT((Vec2(std::stod(cx), std::stod(cy)) - Vec2(std::stod(x), std::stod(y))).norm(),
                1.5) << line;
    }
    // The view cosine at the marker's point: a full dot is seen within 60
    // degrees of square. A whole dot (every disc sample in view, however
    // grazing) has its rim centroid, the full ones' cx, cy.
    const double view_cos = std::stod(cos);
    EXPECT_LE(std::abs(view_cos), 1.0) << line;
    if (disc == "full") {
      EXPECT_GE(view_cos, 0.5 - 1e-3) << line;
      EXPECT_EQ(whole, "1") << line;
      EXPECT_EQ(wcx, cx) << line;
      EXPECT_EQ(wcy, cy) << line;
    }
    if (vis == "1") {
      EXPECT_GT(view_cos, 0.0) << line;
    }
    EXPECT_TRUE(whole == "0" || (whole == "1" && vis == "1")) << line;
    EXPECT_EQ(wcx.empty(), whole != "1") << line;
    grazing_whole += whole == "1" && disc == "partial";
    // A dot is fully visible only if its centre is.
    EXPECT_TRUE(disc == "full" || disc == "partial" || disc == "hidden") << disc;
    EXPECT_EQ(vis == "1", disc != "hidden") << line;
    full += disc == "full";
    const int c = cam == "cam0" ? 0 : 1;
    const Vec3 p = helmet[std::stoi(frame) - 1].bundles.at(marker);
    Vec2 pixel;
    ASSERT_TRUE(rig.cameras[c].camera.Project(rig.cameras[c].cam_from_helmet * p, &pixel));
    EXPECT_LT((pixel - Vec2(std::stod(x), std::stod(y))).norm(), 1e-4);
    ++rows;
    visible += vis == "1";
  }
  EXPECT_GT(rows, 5 * 2 * 100);
  EXPECT_GT(visible, rows / 2);
  EXPECT_GT(full, rows / 10);
  EXPECT_LT(full, visible);
  EXPECT_GT(cut, 0);  // some partial dots are slivers or cut
  EXPECT_GT(grazing_whole, 0);  // and some are whole but seen edge-on
}

}  // namespace
}  // namespace hmc
