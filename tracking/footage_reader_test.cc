#include "tracking/footage_reader.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include "core/error.h"
#include "core/file_util.h"
#include "core/image_io.h"
#include "core/temp_dir.h"

namespace hmc {
namespace {

namespace fs = std::filesystem;

const cv::Size kSize(96, 64);

// A frame whose content names its camera and frame number: a gradient plus
// a square whose position and brightness depend on both.
cv::Mat Pattern(int camera, int frame) {
  cv::Mat image(kSize, CV_8U);
  for (int y = 0; y < image.rows; ++y) {
    for (int x = 0; x < image.cols; ++x) {
      image.at<uint8_t>(y, x) = static_cast<uint8_t>((x + 2 * y + 7 * frame + 50 * camera) % 200);
    }
  }
  cv::rectangle(image, cv::Rect(5 + 3 * frame % 60, 10 + 5 * camera, 12, 12),
                cv::Scalar(230 - 3 * frame), cv::FILLED);
  return image;
}

void WriteFolder(const fs::path& dir, int camera, int first_number, int count,
                 const std::vector<int>& skip = {}) {
  fs::create_directories(dir);
  for (int i = 0; i < count; ++i) {
    if (std::find(skip.begin(), skip.end(), i + 1) != skip.end()) continue;
    const std::string name = fmt::format("frame_{:06d}.png", first_number + i);
    ASSERT_TRUE(cv::imwrite((dir / name).string(), Pattern(camera, i + 1)));
  }
}

void WriteVideo(const fs::path& path, int camera, int count) {
  cv::VideoWriter writer(path.string(), cv::CAP_FFMPEG, cv::VideoWriter::fourcc('F', 'F', 'V', '1'),
                         30, kSize, false);
  ASSERT_TRUE(writer.isOpened());
  for (int f = 1; f <= count; ++f) writer.write(Pattern(camera, f));
}

bool SameImage(const cv::Mat& a, const cv::Mat& b) {
  return a.size() == b.size() && a.type() == b.type() && cv::norm(a, b, cv::NORM_INF) == 0;
}

std::vector<FootageFrame> ReadAll(FootageReader& reader) {
  std::vector<FootageFrame> frames;
  FootageFrame frame;
  while (reader.Next(&frame)) frames.push_back(frame);
  return frames;
}

// A shot numbered from 0 reads as the same shot numbered from 1.
TEST(FootageReaderTest, ImageSequencesNumberedFromZeroOrOneReadTheSame) {
  for (const int first_number : {0, 1}) {
    TempDir dir;
    WriteFolder(dir.path() / "cam0", 0, first_number, 5);
    WriteFolder(dir.path() / "cam1", 1, first_number, 5);
    FootageReader reader(dir.path(), {"cam0", "cam1"}, FootageOptions{});
    EXPECT_EQ(reader.first_frame(), 1);
    EXPECT_EQ(reader.last_frame(), 5);
    EXPECT_TRUE(reader.warnings().empty());
    const std::vector<FootageFrame> frames = ReadAll(reader);
    ASSERT_EQ(frames.size(), 5u);
    for (int i = 0; i < 5; ++i) {
      EXPECT_EQ(frames[i].frame, i + 1);
      ASSERT_TRUE(frames[i].complete());
      EXPECT_TRUE(SameImage(frames[i].images[0], Pattern(0, i + 1)));
      EXPECT_TRUE(SameImage(frames[i].images[1], Pattern(1, i + 1)));
    }
  }
}

// Issue 45, item 1: a camera whose first file is missing starts one frame
// later; every frame pairs the two cameras' files of one number (before:
// each camera was numbered from its own first file, so cam0's file 2 was
// paired with cam1's file 1, silently).
TEST(FootageReaderTest, AMissingFirstFileIsAMissingFrameNotAShift) {
  for (const int missing : {0, 1}) {
    TempDir dir;
    WriteFolder(dir.path() / "cam0", 0, 1, 6, missing == 0 ? std::vector<int>{1} : std::vector<int>{});
    WriteFolder(dir.path() / "cam1", 1, 1, 6, missing == 1 ? std::vector<int>{1} : std::vector<int>{});
    FootageReader reader(dir.path(), {"cam0", "cam1"}, FootageOptions{});
    EXPECT_EQ(reader.first_frame(), 2);
    EXPECT_EQ(reader.last_frame(), 6);
    bool warned = false;
    for (const std::string& w : reader.warnings()) {
      warned |= w.find(fmt::format("cam{} starts at frame 2", missing)) != std::string::npos;
    }
    EXPECT_TRUE(warned);
    const std::vector<FootageFrame> frames = ReadAll(reader);
    ASSERT_EQ(frames.size(), 5u);
    for (const FootageFrame& frame : frames) {
      ASSERT_TRUE(frame.complete()) << frame.frame;
      EXPECT_TRUE(SameImage(frame.images[0], Pattern(0, frame.frame))) << frame.frame;
      EXPECT_TRUE(SameImage(frame.images[1], Pattern(1, frame.frame))) << frame.frame;
    }
  }
}

// Issue 45, item 11: macOS AppleDouble files (`._frame_000001.png`, a few
// bytes of metadata beside every file copied from a Mac) are not frames.
TEST(FootageReaderTest, AppleDoubleFilesAreSkipped) {
  TempDir dir;
  WriteFolder(dir.path() / "cam0", 0, 1, 3);
  WriteFolder(dir.path() / "cam1", 1, 1, 3);
  for (const char* cam : {"cam0", "cam1"}) {
    for (int f = 1; f <= 3; ++f) {
      std::ofstream(dir.path() / cam / fmt::format("._frame_{:06d}.png", f)) << "Mac OS X metadata";
    }
  }
  FootageReader reader(dir.path(), {"cam0", "cam1"}, FootageOptions{});
  const std::vector<FootageFrame> frames = ReadAll(reader);
  ASSERT_EQ(frames.size(), 3u);
  for (const FootageFrame& frame : frames) {
    ASSERT_TRUE(frame.complete()) << frame.frame;
    EXPECT_TRUE(SameImage(frame.images[0], Pattern(0, frame.frame)));
  }
  EXPECT_TRUE(reader.warnings().empty());
}

// The CRC-32 of PNG chunks (ISO 3309), for writing a header by hand.
uint32_t Crc32(const std::string& bytes) {
  uint32_t crc = 0xffffffffu;
  for (const unsigned char c : bytes) {
    crc ^= c;
    for (int k = 0; k < 8; ++k) crc = (crc >> 1) ^ (0xedb88320u & (0u - (crc & 1u)));
  }
  return ~crc;
}

// `png` with its IHDR declaring width x height (CRC fixed, so a decoder
// believes it): what a decompression bomb's header says.
std::string WithDeclaredSize(std::string png, uint32_t width, uint32_t height) {
  for (int i = 0; i < 4; ++i) {
    png[16 + i] = static_cast<char>(width >> (24 - 8 * i));
    png[20 + i] = static_cast<char>(height >> (24 - 8 * i));
  }
  const uint32_t crc = Crc32(png.substr(12, 17));  // "IHDR" and its 13 bytes
  for (int i = 0; i < 4; ++i) png[29 + i] = static_cast<char>(crc >> (24 - 8 * i));
  return png;
}

// Issue 45, items 8 and 11: a frame whose header declares another size
// than the sequence's is a bad frame named by its file, refused before a
// pixel is decoded (a 20000 x 20000 frame: 3.25 GB peak before); an odd
// first file (1x1) does not become the size of the sequence.
TEST(FootageReaderTest, FrameOfAnotherSizeIsRefusedByItsHeader) {
  TempDir dir;
  WriteFolder(dir.path() / "cam0", 0, 1, 5);
  WriteFolder(dir.path() / "cam1", 1, 1, 5);
  const fs::path bomb = dir.path() / "cam0" / "frame_000004.png";
  const std::string bytes = WithDeclaredSize(ReadFile(bomb), 20000, 20000);
  { std::ofstream(bomb, std::ios::binary) << bytes; }
  const fs::path tiny = dir.path() / "cam1" / "frame_000001.png";
  ASSERT_TRUE(cv::imwrite(tiny.string(), cv::Mat(1, 1, CV_8U, cv::Scalar(9))));
  FootageReader reader(dir.path(), {"cam0", "cam1"}, FootageOptions{}, {kSize, kSize});
  const std::vector<FootageFrame> frames = ReadAll(reader);
  ASSERT_EQ(frames.size(), 5u);
  for (const FootageFrame& frame : frames) {
    EXPECT_EQ(frame.images[0].empty(), frame.frame == 4) << frame.frame;
    EXPECT_EQ(frame.images[1].empty(), frame.frame == 1) << frame.frame;
  }
  EXPECT_NE(frames[3].errors[0].find("frame_000004.png is 20000x20000, the sequence is 96x64"),
            std::string::npos)
      << frames[3].errors[0];
  EXPECT_NE(frames[0].errors[1].find("frame_000001.png is 1x1"), std::string::npos)
      << frames[0].errors[1];
}

// Issue 45, second campaign: a shot on a share that goes away mid-run is
// an error naming the source, not a run of bad frames ending in exit 0.
TEST(FootageReaderTest, ASourceThatDisappearsMidReadIsAnError) {
  TempDir dir;
  WriteFolder(dir.path() / "cam0", 0, 1, 5);
  WriteFolder(dir.path() / "cam1", 1, 1, 5);
  FootageReader reader(dir.path(), {"cam0", "cam1"}, FootageOptions{});
  FootageFrame frame;
  ASSERT_TRUE(reader.Next(&frame));
  ASSERT_TRUE(reader.Next(&frame));
  fs::remove_all(dir.path() / "cam1");
  try {
    reader.Next(&frame);
    ADD_FAILURE() << "read on after the footage went away";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("the footage of cam1 disappeared"), std::string::npos)
        << e.what();
  }
}

// Issue 45, item 11: --frames beyond the footage is read as far as there
// is footage, and said.
TEST(FootageReaderTest, FramesBeyondTheFootageAreWarned) {
  TempDir dir;
  WriteFolder(dir.path() / "cam0", 0, 1, 5);
  WriteFolder(dir.path() / "cam1", 1, 1, 5);
  for (const std::string range : {"1:25", "0:3", "-4:"}) {
    FootageOptions options;
    options.frames = range;
    FootageReader reader(dir.path(), {"cam0", "cam1"}, options);
    ASSERT_EQ(reader.warnings().size(), 1u) << range;
    EXPECT_NE(reader.warnings()[0].find("--frames " + range + " reaches beyond the footage's "
                                        "frames 1..5"),
              std::string::npos)
        << reader.warnings()[0];
  }
  FootageOptions inside;
  inside.frames = "2:5";
  EXPECT_TRUE(FootageReader(dir.path(), {"cam0", "cam1"}, inside).warnings().empty());
}

TEST(FootageReaderTest, Ffv1VideoDecodesLosslesslyWithRangeAndOffset) {
  TempDir dir;
  WriteVideo(dir.path() / "cam0.mkv", 0, 12);
  WriteVideo(dir.path() / "cam1.mkv", 1, 12);
  FootageOptions options;
  options.frames = "3:6";
  options.offset1 = 2;  // cam1's frame f + 2 pairs with cam0's frame f
  FootageReader reader(dir.path(), {"cam0", "cam1"}, options, {kSize, kSize});
  const std::vector<FootageFrame> frames = ReadAll(reader);
  ASSERT_EQ(frames.size(), 4u);
  for (size_t i = 0; i < frames.size(); ++i) {
    const int f = 3 + static_cast<int>(i);
    EXPECT_EQ(frames[i].frame, f);
    ASSERT_TRUE(frames[i].complete());
    EXPECT_TRUE(SameImage(frames[i].images[0], Pattern(0, f))) << f;
    EXPECT_TRUE(SameImage(frames[i].images[1], Pattern(1, f + 2))) << f;
  }
}

// Reading a sample of the frames (hmc calibrate) gives exactly those
// frames, each as reading every frame gives it, for videos (passed-over
// frames decoded but not converted, or sought past when far apart) and
// image folders alike. 200 frames: samples far enough apart to seek.
TEST(FootageReaderTest, ASampleOfFramesReadsAsReadingThemAll) {
  TempDir dir;
  WriteVideo(dir.path() / "cam0.mkv", 0, 200);
  WriteFolder(dir.path() / "cam1", 1, 0, 200);
  FootageOptions options;
  options.offset1 = 1;
  FootageReader all_reader(dir.path(), {"cam0", "cam1"}, options);
  const std::vector<FootageFrame> all = ReadAll(all_reader);
  ASSERT_EQ(all.size(), 199u);
  for (const std::vector<int>& sample :
       {std::vector<int>{1, 2, 3}, std::vector<int>{5, 17, 18, 29}, std::vector<int>{29},
        std::vector<int>{10, 90, 150, 151, 199}, std::vector<int>{60, 61, 130},
        std::vector<int>{199}}) {
    FootageReader reader(dir.path(), {"cam0", "cam1"}, options);
    const auto wanted = [&sample](int f) {
      return std::find(sample.begin(), sample.end(), f) != sample.end();
    };
    std::vector<int> got;
    FootageFrame frame;
    while (reader.Next(&frame, wanted)) {
      got.push_back(frame.frame);
      const FootageFrame& same = all[frame.frame - 1];
      ASSERT_EQ(same.frame, frame.frame);
      for (int c = 0; c < 2; ++c) {
        EXPECT_TRUE(SameImage(frame.images[c], same.images[c])) << frame.frame << " cam" << c;
        EXPECT_TRUE(SameImage(frame.images[c], Pattern(c, frame.frame + c))) << frame.frame;
      }
    }
    EXPECT_EQ(got, sample);
  }
}

TEST(FootageReaderTest, DifferentLengthsGiveTheCommonRangeAndAWarning) {
  TempDir dir;
  WriteVideo(dir.path() / "cam0.mkv", 0, 8);
  WriteFolder(dir.path() / "cam1", 1, 1, 6);
  FootageReader reader(dir.path(), {"cam0", "cam1"}, FootageOptions{});
  EXPECT_EQ(reader.first_frame(), 1);
  EXPECT_EQ(reader.last_frame(), 6);
  ASSERT_FALSE(reader.warnings().empty());
  EXPECT_NE(reader.warnings()[0].find("common"), std::string::npos);
  EXPECT_EQ(ReadAll(reader).size(), 6u);
}

TEST(FootageReaderTest, AMissingOrBrokenImageIsReportedAndReadingGoesOn) {
  TempDir dir;
  WriteFolder(dir.path() / "cam0", 0, 1, 6);
  WriteFolder(dir.path() / "cam1", 1, 1, 6, /*skip=*/{3});
  std::ofstream(dir.path() / "cam0" / "frame_000005.png") << "not a png";
  FootageReader reader(dir.path(), {"cam0", "cam1"}, FootageOptions{});
  const std::vector<FootageFrame> frames = ReadAll(reader);
  ASSERT_EQ(frames.size(), 6u);
  for (const FootageFrame& frame : frames) {
    const bool cam0_ok = frame.frame != 5;
    const bool cam1_ok = frame.frame != 3;
    EXPECT_EQ(!frame.images[0].empty(), cam0_ok) << frame.frame;
    EXPECT_EQ(!frame.images[1].empty(), cam1_ok) << frame.frame;
    EXPECT_EQ(frame.errors[0].empty(), cam0_ok);
    EXPECT_EQ(frame.errors[1].empty(), cam1_ok);
    if (cam0_ok) {
      EXPECT_TRUE(SameImage(frame.images[0], Pattern(0, frame.frame)));
    }
    if (cam1_ok) {
      EXPECT_TRUE(SameImage(frame.images[1], Pattern(1, frame.frame)));
    }
  }
  EXPECT_NE(frames[4].errors[0].find("frame_000005.png"), std::string::npos);
}

TEST(FootageReaderTest, SixteenBitAndColourImagesBecomeGreyOfTheirDepth) {
  TempDir dir;
  fs::create_directories(dir.path() / "cam0");
  fs::create_directories(dir.path() / "cam1");
  cv::Mat wide;
  Pattern(0, 1).convertTo(wide, CV_16U, 257.0);
  ASSERT_TRUE(cv::imwrite((dir.path() / "cam0" / "f1.png").string(), wide));
  cv::Mat colour;
  cv::cvtColor(Pattern(1, 1), colour, cv::COLOR_GRAY2BGR);
  ASSERT_TRUE(cv::imwrite((dir.path() / "cam1" / "f1.tif").string(), colour));
  FootageReader reader(dir.path(), {"cam0", "cam1"}, FootageOptions{});
  FootageFrame frame;
  ASSERT_TRUE(reader.Next(&frame));
  EXPECT_EQ(frame.images[0].type(), CV_16U);
  EXPECT_EQ(frame.images[1].type(), CV_8U);
  EXPECT_TRUE(SameImage(ToGrey8(frame.images[0]), Pattern(0, 1)));
  EXPECT_TRUE(SameImage(frame.images[1], Pattern(1, 1)));
  const cv::Mat a = ToGreyFloat(frame.images[0]);
  const cv::Mat b = ToGreyFloat(Pattern(0, 1));
  EXPECT_LT(cv::norm(a, b, cv::NORM_INF), 1e-6);
}

// A plate's own frame numbers are its frames' (issue 44, item 4): a
// sequence 1001-1012 is frames 1001-1012, paired by number, with a gap
// where a file is missing and --frames in the plate's numbers; beside a
// video the folder is numbered from 1 like the video.
TEST(FootageReaderTest, APlatesOwnFrameNumbersAreItsFrames) {
  TempDir dir;
  WriteFolder(dir.path() / "cam0", 0, 1001, 12, {5});
  WriteFolder(dir.path() / "cam1", 1, 1001, 12);
  {
    FootageReader reader(dir.path(), {"cam0", "cam1"}, FootageOptions{});
    EXPECT_EQ(reader.first_frame(), 1001);
    EXPECT_EQ(reader.last_frame(), 1012);
    const std::vector<FootageFrame> frames = ReadAll(reader);
    ASSERT_EQ(frames.size(), 12u);
    for (int i = 0; i < 12; ++i) {
      EXPECT_EQ(frames[i].frame, 1001 + i);
      EXPECT_EQ(frames[i].complete(), i != 4) << frames[i].frame;
      if (i != 4) {
        EXPECT_TRUE(SameImage(frames[i].images[0], Pattern(0, i + 1)));
      }
      EXPECT_TRUE(SameImage(frames[i].images[1], Pattern(1, i + 1)));
    }
  }
  FootageOptions range;
  range.frames = "1003:1004";
  FootageReader ranged(dir.path(), {"cam0", "cam1"}, range);
  const std::vector<FootageFrame> two = ReadAll(ranged);
  ASSERT_EQ(two.size(), 2u);
  EXPECT_EQ(two[0].frame, 1003);
  EXPECT_TRUE(SameImage(two[0].images[1], Pattern(1, 3)));
  // Beside a video: numbered from 1, as the video's frames are.
  fs::remove_all(dir.path() / "cam0");
  WriteVideo(dir.path() / "cam0.mkv", 0, 12);
  FootageReader mixed(dir.path(), {"cam0", "cam1"}, FootageOptions{});
  EXPECT_EQ(mixed.first_frame(), 1);
  EXPECT_EQ(mixed.last_frame(), 12);
}

// A PNG chunk (length, type, data, CRC-32 of type and data) inserted after
// IHDR, as a camera's encoder writes its colour-space chunks.
void InsertPngChunk(const fs::path& path, const std::string& type, const std::string& data) {
  std::string bytes = ReadFile(path);
  std::string chunk;
  for (int shift = 24; shift >= 0; shift -= 8) chunk += static_cast<char>((data.size() >> shift) & 0xff);
  const std::string body = type + data;
  uint32_t crc = 0xffffffffu;
  for (const char ch : body) {
    crc ^= static_cast<uint8_t>(ch);
    for (int k = 0; k < 8; ++k) crc = (crc >> 1) ^ (0xedb88320u & (0u - (crc & 1u)));
  }
  crc ^= 0xffffffffu;
  chunk += body;
  for (int shift = 24; shift >= 0; shift -= 8) chunk += static_cast<char>((crc >> shift) & 0xff);
  bytes.insert(33, chunk);  // 8-byte signature + 25-byte IHDR chunk
  WriteFileAtomic(path, bytes);
}

std::string BigEndian4(uint32_t v) {
  return {static_cast<char>(v >> 24), static_cast<char>((v >> 16) & 0xff),
          static_cast<char>((v >> 8) & 0xff), static_cast<char>(v & 0xff)};
}

// footage.transfer auto: each camera as its first file says (sRGB chunk,
// gAMA, iCCP; nothing said: linear); srgb / linear override. The chunks
// leave the pixels: OpenCV decodes the same (libpng warns that the
// stand-in iCCP profile is too short).
TEST(FootageReaderTest, TransferIsWhatThePngSaysOrTheOption) {
  struct Case {
    std::string chunk_type, chunk_data, expect;
  };
  const std::vector<Case> cases = {
      {"", "", "linear"},
      {"sRGB", std::string(1, '\0'), "srgb"},
      {"gAMA", BigEndian4(45455), "srgb"},
      {"gAMA", BigEndian4(100000), "linear"},
      {"iCCP", std::string("sRGB IEC61966-2.1") + '\0' + '\0' + "xx", "srgb"},
      {"iCCP", std::string("Linear Rec709") + '\0' + '\0' + "xx", "linear"},
  };
  for (const Case& c : cases) {
    TempDir dir;
    WriteFolder(dir.path() / "cam0", 0, 1, 2);
    WriteFolder(dir.path() / "cam1", 1, 1, 2);
    if (!c.chunk_type.empty()) {
      for (const char* name : {"frame_000001.png", "frame_000002.png"}) {
        InsertPngChunk(dir.path() / "cam1" / name, c.chunk_type, c.chunk_data);
      }
    }
    for (const std::string option : {"auto", "srgb", "linear"}) {
      FootageOptions options;
      options.transfer = option;
      FootageReader reader(dir.path(), {"cam0", "cam1"}, options);
      const std::string expect = option == "auto" ? c.expect : option;
      EXPECT_EQ(reader.transfer(1), expect) << c.chunk_type << " " << option << ": "
                                            << reader.transfer_why(1);
      EXPECT_EQ(reader.transfer(0), option == "auto" ? "linear" : option);
      FootageFrame frame;
      ASSERT_TRUE(reader.Next(&frame));
      EXPECT_TRUE(SameImage(frame.images[1], Pattern(1, 1))) << c.chunk_type;
    }
  }
}

// An ISO BMFF box: 32-bit size, type, body.
std::string Box(const std::string& type, const std::string& body) {
  return BigEndian4(static_cast<uint32_t>(8 + body.size())) + type + body;
}

// An .mp4/.mov's colr box names its transfer (H.273 codes): found under
// moov/trak/mdia/minf/stbl/stsd/<sample entry>, wherever moov lies; the
// BT.709 family is read as sRGB, 8 as linear, the rest as not said.
TEST(FootageReaderTest, AVideosColrBoxGivesItsTransfer) {
  TempDir dir;
  auto write = [&](const std::string& name, const std::string& colr_kind, int transfer,
                   bool moov_last) {
    const std::string colr =
        colr_kind.empty() ? ""
                          : Box("colr", colr_kind + std::string("\0\1", 2) +
                                            std::string(1, '\0') + static_cast<char>(transfer) +
                                            std::string("\0\1", 2) +
                                            (colr_kind == "nclx" ? std::string(1, '\0') : ""));
    const std::string entry = Box("avc1", std::string(78, '\0') + Box("avcC", "xyz") + colr);
    const std::string stsd = Box("stsd", std::string(7, '\0') + '\1' + entry);
    const std::string moov = Box(
        "moov", Box("mvhd", std::string(20, '\0')) +
                    Box("trak", Box("mdia", Box("minf", Box("stbl", stsd)))));
    const std::string mdat = Box("mdat", std::string(100, '\7'));
    const std::string ftyp = Box("ftyp", "isom\0\0\2\0");
    WriteFileAtomic(dir.path() / name, ftyp + (moov_last ? mdat + moov : moov + mdat));
    return dir.path() / name;
  };
  std::string why;
  EXPECT_EQ(VideoTransfer(write("a.mp4", "nclx", 1, false), &why), "srgb") << why;
  EXPECT_EQ(VideoTransfer(write("b.mov", "nclc", 1, true), &why), "srgb") << why;
  EXPECT_EQ(VideoTransfer(write("c.mp4", "nclx", 13, true), &why), "srgb") << why;
  EXPECT_EQ(VideoTransfer(write("d.mp4", "nclx", 8, false), &why), "linear") << why;
  EXPECT_EQ(VideoTransfer(write("e.mp4", "nclx", 2, false), &why), "") << why;
  EXPECT_EQ(VideoTransfer(write("f.mp4", "nclx", 16, false), &why), "") << why;  // PQ
  EXPECT_NE(why.find("does not invert"), std::string::npos) << why;
  EXPECT_EQ(VideoTransfer(write("g.mp4", "", 0, false), &why), "") << why;
  EXPECT_EQ(VideoTransfer(write("h.mkv", "nclx", 1, false), &why), "") << why;
  // What OpenCV's writer makes says nothing: read as linear (auto).
  WriteVideo(dir.path() / "cam0.mkv", 0, 2);
  WriteVideo(dir.path() / "cam1.mkv", 1, 2);
  FootageReader reader(dir.path(), {"cam0", "cam1"}, FootageOptions{});
  EXPECT_EQ(reader.transfer(0), "linear") << reader.transfer_why(0);
}

// Linearize turns an sRGB camera's 8- or 16-bit values into linear light
// (16-bit), within the encoding's quantisation; a linear camera's images
// stay as they are.
TEST(FootageReaderTest, SrgbFramesAreLinearisedWithinQuantisation) {
  TempDir dir;
  fs::create_directories(dir.path() / "cam0");
  fs::create_directories(dir.path() / "cam1");
  // A linear ramp over [0, 1], encoded by the sRGB curve to 8 and 16 bit.
  cv::Mat linear(kSize, CV_64F);
  for (int y = 0; y < kSize.height; ++y) {
    for (int x = 0; x < kSize.width; ++x) {
      linear.at<double>(y, x) = (y * kSize.width + x) / (kSize.area() - 1.0);
    }
  }
  auto encode = [&](double full_scale, int type) {
    cv::Mat out(kSize, type);
    for (int y = 0; y < kSize.height; ++y) {
      for (int x = 0; x < kSize.width; ++x) {
        const double v = linear.at<double>(y, x);
        const double e = v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1 / 2.4) - 0.055;
        const double q = std::round(e * full_scale);
        if (type == CV_8U) out.at<uint8_t>(y, x) = static_cast<uint8_t>(q);
        else out.at<uint16_t>(y, x) = static_cast<uint16_t>(q);
      }
    }
    return out;
  };
  WritePng(dir.path() / "cam0" / "f1.png", encode(255, CV_8U), true);
  WritePng(dir.path() / "cam1" / "f1.png", encode(65535, CV_16U), true);
  FootageReader reader(dir.path(), {"cam0", "cam1"}, FootageOptions{});
  ASSERT_EQ(reader.transfer(0), "srgb") << reader.transfer_why(0);
  ASSERT_EQ(reader.transfer(1), "srgb") << reader.transfer_why(1);
  FootageFrame frame;
  ASSERT_TRUE(reader.Next(&frame));
  const cv::Mat stored8 = frame.images[0].clone();
  reader.Linearize(&frame);
  for (int c = 0; c < 2; ++c) {
    ASSERT_EQ(frame.images[c].type(), CV_16U);
    cv::Mat read;
    frame.images[c].convertTo(read, CV_64F, 1 / 65535.0);
    // Half a step of the encoding in linear terms where it is widest (the
    // sRGB decoding curve's slope is at most 2.4 / 1.055, at full scale),
    // plus the 16-bit output's rounding.
    const double step = (c == 0 ? 1 / 255.0 : 1 / 65535.0) * 2.4 / 1.055;
    EXPECT_LT(cv::norm(read, linear, cv::NORM_INF), 0.5 * step + 1 / 65535.0) << "cam" << c;
  }
  // Read as stored, the same values are far from linear (mid-grey 0.5 is
  // stored as 0.735).
  cv::Mat as_stored;
  stored8.convertTo(as_stored, CV_64F, 1 / 255.0);
  EXPECT_GT(cv::norm(as_stored, linear, cv::NORM_INF), 0.2);
  // A linear camera: untouched.
  FootageOptions linear_options;
  linear_options.transfer = "linear";
  FootageReader plain(dir.path(), {"cam0", "cam1"}, linear_options);
  ASSERT_TRUE(plain.Next(&frame));
  const cv::Mat before = frame.images[0].clone();
  plain.Linearize(&frame);
  EXPECT_TRUE(SameImage(frame.images[0], before));
}

std::string ErrorOf(const fs::path& shot, const FootageOptions& options,
                    const std::vector<cv::Size>& sizes = {}) {
  try {
    FootageReader reader(shot, {"cam0", "cam1"}, options, sizes);
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

TEST(FootageReaderTest, BadSourcesAreRefusedWithThePathNamed) {
  TempDir dir;
  const fs::path shot = dir.path();
  EXPECT_NE(ErrorOf(shot / "nope", {}).find("nope"), std::string::npos);
  WriteVideo(shot / "cam0.mkv", 0, 3);
  EXPECT_NE(ErrorOf(shot, {}).find("no footage for camera cam1"), std::string::npos);
  std::ofstream(shot / "cam1.mkv") << "this is not a video";
  EXPECT_NE(ErrorOf(shot, {}).find("cam1.mkv"), std::string::npos);
  fs::remove(shot / "cam1.mkv");
  WriteVideo(shot / "cam1.mkv", 1, 3);
  const std::string wrong = ErrorOf(shot, {}, {kSize, cv::Size(1280, 1024)});
  EXPECT_NE(wrong.find("cam1.mkv"), std::string::npos) << wrong;
  EXPECT_NE(wrong.find("1280x1024"), std::string::npos) << wrong;
  EXPECT_EQ(wrong.find("turned"), std::string::npos) << wrong;
  // Width and height exchanged: footage turned by its rotation metadata.
  const std::string turned = ErrorOf(shot, {}, {kSize, cv::Size(kSize.height, kSize.width)});
  EXPECT_NE(turned.find("turned by 90 degrees"), std::string::npos) << turned;
  // Issue 45, item 9: a still image under a video's name is not a
  // one-frame video of unknown length.
  ASSERT_TRUE(cv::imwrite((shot / "still.png").string(), Pattern(1, 1)));
  fs::rename(shot / "cam1.mkv", shot / "cam1.bak");
  fs::copy_file(shot / "still.png", shot / "cam1.mkv");
  const std::string still = ErrorOf(shot, {});
  EXPECT_NE(still.find("cam1.mkv"), std::string::npos) << still;
  EXPECT_NE(still.find("not a video but a PNG image"), std::string::npos) << still;
  // Issue 45, item 11: a cam1/ that links to itself is named for what it
  // is, without a flag that hmc run does not have.
  fs::remove(shot / "cam1.mkv");
  fs::create_directory_symlink("cam1", shot / "cam1");
  const std::string loop = ErrorOf(shot, {});
  EXPECT_NE(loop.find((shot / "cam1").string() + ": the footage of cam1"), std::string::npos)
      << loop;
  EXPECT_EQ(loop.find("--cam1"), std::string::npos) << loop;
  fs::remove(shot / "cam1");
  fs::rename(shot / "cam1.bak", shot / "cam1.mkv");
  FootageOptions bad_range;
  bad_range.frames = "9:";
  EXPECT_NE(ErrorOf(shot, bad_range).find("no frame in common"), std::string::npos);
  EXPECT_THROW(ParseFrameRange("5:2", "--frames"), InputError);
  EXPECT_THROW(ParseFrameRange("a:b", "--frames"), InputError);
  EXPECT_EQ(ParseFrameRange(":7", "--frames").last, 7);
}

// A truncated video gives the frames that decode and a warning.
TEST(FootageReaderTest, TruncatedVideoGivesWhatDecodes) {
  TempDir dir;
  WriteVideo(dir.path() / "cam0.mkv", 0, 20);
  WriteVideo(dir.path() / "cam1.mkv", 1, 20);
  const fs::path p = dir.path() / "cam1.mkv";
  fs::resize_file(p, fs::file_size(p) * 6 / 10);
  FootageReader reader(dir.path(), {"cam0", "cam1"}, FootageOptions{});
  const std::vector<FootageFrame> frames = ReadAll(reader);
  ASSERT_GE(frames.size(), 5u);
  EXPECT_LT(frames.size(), 20u);
  for (const FootageFrame& frame : frames) {
    if (!frame.images[1].empty()) {
      EXPECT_TRUE(SameImage(frame.images[1], Pattern(1, frame.frame))) << frame.frame;
    }
  }
  EXPECT_FALSE(reader.warnings().empty());
}

}  // namespace
}  // namespace hmc

namespace hmc {
namespace {

// Bytes overwritten in the middle of a video (FFV1 carries no checksum
// here): the frames they hit come back flagged or garbled; no frame comes
// back under another frame's number, and the frames after the damage are
// intact.
TEST(FootageReaderTest, CorruptBytesMidVideoDoNotShiftLaterFrames) {
  TempDir dir;
  WriteVideo(dir.path() / "cam0.mkv", 0, 20);
  WriteVideo(dir.path() / "cam1.mkv", 1, 20);
  const fs::path p = dir.path() / "cam1.mkv";
  const uintmax_t size = fs::file_size(p);
  {
    std::fstream f(p, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(static_cast<std::streamoff>(size / 2));
    const std::string garbage(400, '\x5a');
    f.write(garbage.data(), static_cast<std::streamsize>(garbage.size()));
  }
  FootageReader reader(dir.path(), {"cam0", "cam1"}, FootageOptions{});
  const std::vector<FootageFrame> frames = ReadAll(reader);
  ASSERT_EQ(frames.size(), 20u);
  int damaged = 0, last_damaged = 0, shifted = 0;
  for (const FootageFrame& frame : frames) {
    EXPECT_TRUE(SameImage(frame.images[0], Pattern(0, frame.frame)));
    const cv::Mat& image = frame.images[1];
    if (!image.empty() && SameImage(image, Pattern(1, frame.frame))) continue;
    ++damaged;
    last_damaged = frame.frame;
    for (int other = 1; other <= 20; ++other) {
      shifted += other != frame.frame && !image.empty() && SameImage(image, Pattern(1, other));
    }
  }
  EXPECT_GE(damaged, 1);           // the damage is seen
  EXPECT_EQ(shifted, 0);           // and never shifts a frame
  EXPECT_LT(last_damaged, 16);     // the frames after it are intact
}

}  // namespace
}  // namespace hmc
