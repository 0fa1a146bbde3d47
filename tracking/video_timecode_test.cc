#include "tracking/video_timecode.h"

#include <cstdlib>
#include <string>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <opencv2/videoio.hpp>

#include "core/error.h"
#include "core/temp_dir.h"

namespace hmc {
namespace {

namespace fs = std::filesystem;

// SMPTE arithmetic, non-drop and drop-frame (at 29.97 frame numbers 0 and 1
// are skipped at every minute but each tenth).
TEST(VideoTimecodeTest, AdvancesNonDropAndDropFrameTimecodes) {
  EXPECT_EQ(AdvanceTimecode("01:02:03:04", 30, 0, "t"), "01:02:03:04");
  EXPECT_EQ(AdvanceTimecode("01:02:03:04", 30, 26, "t"), "01:02:04:00");
  EXPECT_EQ(AdvanceTimecode("10:00:00:24", 25, 1, "t"), "10:00:01:00");
  EXPECT_EQ(AdvanceTimecode("23:59:59:23", 24, 1, "t"), "00:00:00:00");
  EXPECT_EQ(AdvanceTimecode("00:00:59;29", 29.97, 1, "t"), "00:01:00;02");
  EXPECT_EQ(AdvanceTimecode("00:00:59;29", 30000.0 / 1001, 1, "t"), "00:01:00;02");
  EXPECT_EQ(AdvanceTimecode("00:09:59;29", 29.97, 1, "t"), "00:10:00;00");
  // One hour of 29.97 drop-frame is 107892 frames.
  EXPECT_EQ(AdvanceTimecode("00:00:00;00", 29.97, 107892, "t"), "01:00:00;00");
  EXPECT_EQ(AdvanceTimecode("01:00:00:00", 60, 60 * 60, "t"), "01:01:00:00");
}

TEST(VideoTimecodeTest, MalformedTimecodesAreRefusedWithTheirOrigin) {
  for (const char* bad : {"01:02:03", "01:02:03:30", "01:60:00:00", "ab:cd:ef:gh", ""}) {
    try {
      AdvanceTimecode(bad, 30, 0, "--timecode");
      ADD_FAILURE() << bad << " was accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("--timecode"), std::string::npos) << e.what();
    }
  }
  EXPECT_THROW(AdvanceTimecode("01:02:03:04", 0, 1, "t"), InputError);
}

// What FFmpeg's own muxers write: Matroska's TIMECODE tag and a QuickTime
// tmcd track (drop-frame); OpenCV's writer and a non-video write none.
TEST(VideoTimecodeTest, ReadsTheTimecodeContainersCarry) {
  TempDir dir("hmc_video_timecode");
  {
    cv::VideoWriter writer((dir.path() / "plain.avi").string(), cv::CAP_FFMPEG,
                           cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), 30, cv::Size(64, 48));
    ASSERT_TRUE(writer.isOpened());
    for (int i = 0; i < 3; ++i) writer.write(cv::Mat(48, 64, CV_8UC3, cv::Scalar(i * 40)));
  }
  EXPECT_EQ(ReadVideoTimecode(dir.path() / "plain.avi"), "");
  EXPECT_EQ(ReadVideoTimecode(dir.path() / "missing.mkv"), "");
  if (std::system("command -v ffmpeg > /dev/null 2>&1") != 0) {
    GTEST_SKIP() << "ffmpeg is not installed (scripts/setup installs it): the containers with a "
                    "timecode are not written";
  }
  struct Case {
    const char* file;
    const char* rate;
    const char* codec;
    const char* timecode;
  };
  for (const Case& c : {Case{"a.mkv", "30", "ffv1", "01:02:03:04"},
                        Case{"b.mov", "30000/1001", "mpeg4", "00:00:59;29"},
                        Case{"c.mp4", "25", "mpeg4", "10:00:00:00"}}) {
    const fs::path path = dir.path() / c.file;
    const std::string command = fmt::format(
        "ffmpeg -loglevel error -y -f lavfi -i testsrc=size=64x48:rate={} -frames:v 3 "
        "-timecode '{}' -c:v {} '{}'",
        c.rate, c.timecode, c.codec, path.string());
    ASSERT_EQ(std::system(command.c_str()), 0) << command;
    EXPECT_EQ(ReadVideoTimecode(path), c.timecode) << c.file;
  }
}

}  // namespace
}  // namespace hmc
