#include "core/frame_data.h"

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <limits>
#include <random>
#include <string>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "core/temp_dir.h"

#include "core/error.h"
#include "core/file_util.h"

namespace hmc {
namespace {

namespace fs = std::filesystem;

// Doubles over many magnitudes, including ones with no short decimal form.
double RandomValue(std::mt19937& rng) {
  std::uniform_real_distribution<double> mantissa(-1.0, 1.0);
  std::uniform_int_distribution<int> exponent(-30, 30);
  return std::ldexp(mantissa(rng), exponent(rng));
}

std::vector<BundleFrame> RandomBundles(unsigned seed) {
  std::mt19937 rng(seed);
  std::bernoulli_distribution present(0.7);
  std::vector<BundleFrame> frames;
  int frame = static_cast<int>(seed % 5) - 2;
  for (int i = 0; i < 6; ++i) {
    BundleFrame bundle_frame;
    bundle_frame.frame = frame;
    frame += 1 + static_cast<int>(rng() % 3);  // gaps are allowed
    for (int m = 0; m < 12; ++m) {
      if (!present(rng)) continue;  // a missing marker has no row
      bundle_frame.bundles[fmt::format("marker_{}.L", m)] =
          Vec3(RandomValue(rng), RandomValue(rng), RandomValue(rng));
    }
    if (!bundle_frame.bundles.empty()) frames.push_back(bundle_frame);
  }
  return frames;
}

template <typename Fn>
void ExpectErrorAtLine(const fs::path& file, int line, Fn read,
                       const std::string& message_part) {
  try {
    read();
    ADD_FAILURE() << "no error; expected line " << line << ": "
                  << message_part;
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), file);
    EXPECT_EQ(e.line(), line) << e.what();
    EXPECT_NE(std::string(e.what()).find(message_part), std::string::npos)
        << e.what();
  }
}

class FrameDataSeeded : public ::testing::TestWithParam<unsigned> {};

TEST_P(FrameDataSeeded, BundlesRoundTripExactly) {
  const TempDir temp_dir("hmc_frame_data_" + std::string("bundles_" + std::to_string(GetParam())));
  const fs::path& dir = temp_dir.path();
  const std::vector<BundleFrame> frames = RandomBundles(GetParam());
  WriteBundlesCsv(dir / "bundles.csv", frames);
  const std::vector<BundleFrame> back = ReadBundlesCsv(dir / "bundles.csv");
  ASSERT_EQ(back.size(), frames.size());
  for (size_t i = 0; i < frames.size(); ++i) {
    EXPECT_EQ(back[i].frame, frames[i].frame);
    ASSERT_EQ(back[i].bundles.size(), frames[i].bundles.size());
    for (const auto& [marker, position] : frames[i].bundles) {
      ASSERT_EQ(back[i].bundles.count(marker), 1u) << marker;
      EXPECT_TRUE(back[i].bundles.at(marker) == position) << marker;
    }
  }
}

TEST_P(FrameDataSeeded, JawRoundTripsExactly) {
  const TempDir temp_dir("hmc_frame_data_" + std::string("jaw_" + std::to_string(GetParam())));
  const fs::path& dir = temp_dir.path();
  std::mt19937 rng(GetParam());
  std::vector<JawFrame> frames(7);
  for (size_t i = 0; i < frames.size(); ++i) {
    frames[i].frame = static_cast<int>(GetParam()) + 2 * static_cast<int>(i);
    frames[i].pose = JawPose::FromArray(
        {RandomValue(rng), RandomValue(rng), RandomValue(rng)});
  }
  WriteJawCsv(dir / "jaw.csv", frames);
  const std::vector<JawFrame> back = ReadJawCsv(dir / "jaw.csv");
  ASSERT_EQ(back.size(), frames.size());
  for (size_t i = 0; i < frames.size(); ++i) {
    EXPECT_EQ(back[i].frame, frames[i].frame);
    EXPECT_TRUE(back[i].pose.ToArray() == frames[i].pose.ToArray());
  }
}

TEST_P(FrameDataSeeded, PosesRoundTripExactly) {
  const TempDir temp_dir("hmc_frame_data_" + std::string("poses_" + std::to_string(GetParam())));
  const fs::path& dir = temp_dir.path();
  std::mt19937 rng(GetParam());
  std::normal_distribution<double> normal;
  std::vector<PoseFrame> frames(6);
  for (size_t i = 0; i < frames.size(); ++i) {
    frames[i].frame = static_cast<int>(GetParam()) + 3 * static_cast<int>(i);
    const Vec3 axis = Vec3(normal(rng), normal(rng), normal(rng)).normalized();
    frames[i].pose.linear() =
        Eigen::AngleAxisd(normal(rng), axis).toRotationMatrix();
    frames[i].pose.translation() =
        Vec3(RandomValue(rng), RandomValue(rng), RandomValue(rng));
  }
  WritePosesCsv(dir / "head_from_helmet.csv", frames);
  const std::vector<PoseFrame> back = ReadPosesCsv(dir / "head_from_helmet.csv");
  ASSERT_EQ(back.size(), frames.size());
  for (size_t i = 0; i < frames.size(); ++i) {
    EXPECT_EQ(back[i].frame, frames[i].frame);
    EXPECT_TRUE(back[i].pose.matrix() == frames[i].pose.matrix());
  }
}

INSTANTIATE_TEST_SUITE_P(Seeds, FrameDataSeeded,
                         ::testing::Values(1u, 2u, 5u, 23u));

TEST(FrameDataTest, HeadersAreTheDocumentedOnes) {
  const TempDir temp_dir("hmc_frame_data_" + std::string("headers"));
  const fs::path& dir = temp_dir.path();
  WriteBundlesCsv(dir / "bundles.csv", {});
  EXPECT_EQ(ReadFile(dir / "bundles.csv"), "frame,marker,x,y,z\n");
  WriteJawCsv(dir / "jaw.csv", {});
  const auto& names = JawPose::ParameterNames();
  EXPECT_EQ(ReadFile(dir / "jaw.csv"),
            fmt::format("frame,{},{},{}\n", names[0], names[1], names[2]));
  EXPECT_TRUE(ReadBundlesCsv(dir / "bundles.csv").empty());
  EXPECT_TRUE(ReadJawCsv(dir / "jaw.csv").empty());
}

TEST(FrameDataTest, RowsInAnyOrderComeBackByFrame) {
  const TempDir temp_dir("hmc_frame_data_" + std::string("order"));
  const fs::path& dir = temp_dir.path();
  const fs::path file = dir / "bundles.csv";
  WriteFileAtomic(file,
                  "frame,marker,x,y,z\r\n"
                  "5,b,1,2,3\r\n"
                  "2, a , 4.5, -6, 7e-3\r\n"
                  "\r\n"
                  "5,a,0,0,0\r\n");
  const std::vector<BundleFrame> frames = ReadBundlesCsv(file);
  ASSERT_EQ(frames.size(), 2u);
  EXPECT_EQ(frames[0].frame, 2);
  EXPECT_EQ(frames[1].frame, 5);
  EXPECT_EQ(frames[0].bundles.at("a"), Vec3(4.5, -6, 7e-3));
  EXPECT_EQ(frames[1].bundles.size(), 2u);
}

TEST(FrameDataTest, BadBundlesAreRefusedWithFileAndLine) {
  const TempDir temp_dir("hmc_frame_data_" + std::string("bad_bundles"));
  const fs::path& dir = temp_dir.path();
  const fs::path file = dir / "bundles.csv";
  struct Case {
    std::string text;
    int line;
    std::string message;
  };
  const std::vector<Case> cases = {
      {"", 0, "header"},
      {"frame,marker,x,y\n1,a,1,2\n", 1, "header"},
      {"frame,marker,x,y,z\n1,a,1,2\n", 2, "fields"},
      {"frame,marker,x,y,z\n1,a,1,2,3\n1,b,1,2,3,4\n", 3, "fields"},
      {"frame,marker,x,y,z\n1.5,a,1,2,3\n", 2, "integer"},
      {"frame,marker,x,y,z\n1,a,1,two,3\n", 2, "not a number"},
      {"frame,marker,x,y,z\n1,a,1,2,3x\n", 2, "not a number"},
      {"frame,marker,x,y,z\n1,a,1,nan,3\n", 2, "finite"},
      {"frame,marker,x,y,z\n1,a,1,2,-inf\n", 2, "finite"},
      {"frame,marker,x,y,z\n1,a,1,2,1e999\n", 2, "not a number"},
      {"frame,marker,x,y,z\n1,,1,2,3\n", 2, "empty marker"},
      {"frame,marker,x,y,z\n1,a,1,2,3\n2,a,1,2,3\n1,a,4,5,6\n", 4,
       "repeated in frame 1 (first on line 2)"},
  };
  for (const Case& c : cases) {
    WriteFileAtomic(file, c.text);
    ExpectErrorAtLine(file, c.line, [&] { ReadBundlesCsv(file); }, c.message);
  }
  ExpectErrorAtLine(dir / "missing.csv", 0,
                    [&] { ReadBundlesCsv(dir / "missing.csv"); },
                    "does not exist");
}

TEST(FrameDataTest, BadJawIsRefusedWithFileAndLine) {
  const TempDir temp_dir("hmc_frame_data_" + std::string("bad_jaw"));
  const fs::path& dir = temp_dir.path();
  const fs::path file = dir / "jaw.csv";
  const std::string header = "frame,open_deg,lateral_deg,protrude_mm\n";
  WriteFileAtomic(file, "frame,open,lateral,protrude\n1,0,0,0\n");
  ExpectErrorAtLine(file, 1, [&] { ReadJawCsv(file); }, "header");
  WriteFileAtomic(file, header + "1,0,0,0\n2,1,inf,0\n");
  ExpectErrorAtLine(file, 3, [&] { ReadJawCsv(file); }, "finite");
  WriteFileAtomic(file, header + "1,0,0\n");
  ExpectErrorAtLine(file, 2, [&] { ReadJawCsv(file); }, "fields");
  WriteFileAtomic(file, header + "3,0,0,0\n1,0,0,0\n3,1,1,1\n");
  ExpectErrorAtLine(file, 4, [&] { ReadJawCsv(file); },
                    "frame 3 repeated (first on line 2)");
}

TEST(FrameDataTest, BadPosesAreRefusedWithFileAndLine) {
  const TempDir temp_dir("hmc_frame_data_" + std::string("bad_poses"));
  const fs::path& dir = temp_dir.path();
  const fs::path file = dir / "head_from_helmet.csv";
  const std::string header =
      "frame,r00,r01,r02,r10,r11,r12,r20,r21,r22,tx,ty,tz\n";
  WriteFileAtomic(file, header + "1,1,0,0,0,1,0,0,0,1,0,0,0\n"
                                 "2,1,0,0,0,1,0,0,0,2,0,0,0\n");
  ExpectErrorAtLine(file, 3, [&] { ReadPosesCsv(file); }, "not a rotation");
  WriteFileAtomic(file, header + "1,1,0,0,0,1,0,0,0,-1,0,0,0\n");
  ExpectErrorAtLine(file, 2, [&] { ReadPosesCsv(file); }, "not a rotation");
  WriteFileAtomic(file, header + "4,1,0,0,0,1,0,0,0,1,0,0,0\n"
                                 "4,1,0,0,0,1,0,0,0,1,0,0,0\n");
  ExpectErrorAtLine(file, 3, [&] { ReadPosesCsv(file); },
                    "frame 4 repeated (first on line 2)");
  WriteFileAtomic(file, header + "1,1,0,0,0,1,0,0,0,1,0,0\n");
  ExpectErrorAtLine(file, 2, [&] { ReadPosesCsv(file); }, "fields");
}

TEST(FrameDataTest, WritersRefuseWhatCannotBeReadBack) {
  const TempDir temp_dir("hmc_frame_data_" + std::string("refuse"));
  const fs::path& dir = temp_dir.path();
  BundleFrame frame;
  frame.frame = 1;
  frame.bundles["a,b"] = Vec3::Zero();
  EXPECT_THROW(WriteBundlesCsv(dir / "bundles.csv", {frame}), InputError);
  frame.bundles.clear();
  frame.bundles["a"] = Vec3(0, std::numeric_limits<double>::infinity(), 0);
  EXPECT_THROW(WriteBundlesCsv(dir / "bundles.csv", {frame}), InputError);
  frame.bundles["a"] = Vec3::Zero();
  EXPECT_THROW(WriteBundlesCsv(dir / "bundles.csv", {frame, frame}),
               InputError);
  EXPECT_FALSE(fs::exists(dir / "bundles.csv"));

  JawFrame jaw;
  jaw.pose.open_deg = std::nan("");
  EXPECT_THROW(WriteJawCsv(dir / "jaw.csv", {jaw}), InputError);
  jaw.pose.open_deg = 1;
  EXPECT_THROW(WriteJawCsv(dir / "jaw.csv", {jaw, jaw}), InputError);
  EXPECT_FALSE(fs::exists(dir / "jaw.csv"));
  EXPECT_TRUE(fs::is_empty(dir));  // no temporaries either
}

}  // namespace
}  // namespace hmc
