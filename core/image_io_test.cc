#include "core/image_io.h"

#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <random>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <unistd.h>

#include "core/error.h"
#include "core/file_util.h"

namespace hmc {
namespace {

class ImageIoTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("hmc_image_io_test_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::filesystem::path dir_;
};

cv::Mat RandomImage(int rows, int cols, int type, unsigned seed) {
  cv::Mat image(rows, cols, type);
  cv::theRNG().state = seed;
  cv::randu(image, cv::Scalar::all(0),
            cv::Scalar::all(CV_MAT_DEPTH(type) == CV_16U ? 65536 : 256));
  return image;
}

TEST_F(ImageIoTest, PngRoundTripIsExact) {
  unsigned seed = 1;
  for (const int type : {CV_8UC1, CV_8UC3, CV_8UC4, CV_16UC1, CV_16UC3}) {
    const cv::Mat image = RandomImage(37 + seed, 53, type, seed);
    const auto path = dir_ / ("image" + std::to_string(seed++) + ".png");
    WritePng(path, image);
    const cv::Mat back = ReadPng(path);
    ASSERT_EQ(back.type(), image.type());
    ASSERT_EQ(back.size(), image.size());
    EXPECT_EQ(cv::norm(back, image, cv::NORM_INF), 0) << cv::typeToString(type);
  }
  // A view into a larger image (non-continuous rows) is written as seen.
  const cv::Mat big = RandomImage(40, 40, CV_8UC3, 9);
  const cv::Mat roi = big(cv::Rect(5, 7, 20, 11));
  WritePng(dir_ / "roi.png", roi);
  EXPECT_EQ(cv::norm(ReadPng(dir_ / "roi.png"), roi, cv::NORM_INF), 0);
}

// A PNG written with declare_srgb says so in its header (an sRGB chunk,
// which libpng accepts: the pixels read back exact); one without says
// nothing; a JPEG is sRGB by convention.
TEST_F(ImageIoTest, PngDeclaresSrgbWhenAsked) {
  unsigned seed = 3;
  for (const int type : {CV_8UC1, CV_16UC1, CV_8UC3}) {
    const cv::Mat image = RandomImage(21, 34, type, seed++);
    WritePng(dir_ / "srgb.png", image, true);
    WritePng(dir_ / "plain.png", image);
    const ImageHeader srgb = ReadImageHeader(dir_ / "srgb.png");
    EXPECT_EQ(srgb.format, "PNG");
    EXPECT_EQ(srgb.size, image.size());
    EXPECT_EQ(srgb.transfer, "srgb") << srgb.transfer_why;
    EXPECT_EQ(ReadImageHeader(dir_ / "plain.png").transfer, "");
    EXPECT_EQ(cv::norm(ReadPng(dir_ / "srgb.png"), image, cv::NORM_INF), 0);
  }
  ASSERT_TRUE(cv::imwrite((dir_ / "f.jpg").string(), RandomImage(8, 8, CV_8UC1, 1)));
  EXPECT_EQ(ReadImageHeader(dir_ / "f.jpg").transfer, "srgb");
}

TEST_F(ImageIoTest, PngRejectsBadInputAndLeavesNoFile) {
  EXPECT_THROW(WritePng(dir_ / "empty.png", cv::Mat()), InputError);
  EXPECT_THROW(WritePng(dir_ / "float.png", cv::Mat(4, 4, CV_32FC1)),
               InputError);
  EXPECT_THROW(WritePng(dir_ / "no_such_dir" / "a.png",
                        cv::Mat(4, 4, CV_8UC1, cv::Scalar(1))),
               InputError);
  EXPECT_FALSE(std::filesystem::exists(dir_ / "empty.png"));
  EXPECT_FALSE(std::filesystem::exists(dir_ / "float.png"));
  EXPECT_TRUE(std::filesystem::is_empty(dir_));  // no temporaries left
  EXPECT_THROW(ReadPng(dir_ / "missing.png"), InputError);
  WriteFileAtomic(dir_ / "garbage.png", "not a png");
  EXPECT_THROW(ReadPng(dir_ / "garbage.png"), InputError);
}

// Issue 45, item 8: the header gives the size OpenCV decodes, for each
// format a camera writes, without decoding; anything else is "" with why.
TEST_F(ImageIoTest, HeaderSizeMatchesTheDecodedSize) {
  unsigned seed = 3;
  for (const char* ext : {".png", ".jpg", ".tif"}) {
    for (const int type : {CV_8UC1, CV_8UC3}) {
      const cv::Mat image = RandomImage(29 + seed, 71 - seed, type, seed);
      const auto path = dir_ / ("h" + std::to_string(seed++) + ext);
      ASSERT_TRUE(cv::imwrite(path.string(), image));
      const ImageHeader h = ReadImageHeader(path);
      EXPECT_EQ(h.size, cv::imread(path.string(), cv::IMREAD_UNCHANGED).size()) << path;
      EXPECT_FALSE(h.format.empty()) << path << ": " << h.error;
    }
  }
  WriteFileAtomic(dir_ / "garbage.png", "not a png at all");
  EXPECT_TRUE(ReadImageHeader(dir_ / "garbage.png").format.empty());
  WriteFileAtomic(dir_ / "cut.png", ReadFile(dir_ / "h3.png").substr(0, 20));  // inside IHDR
  EXPECT_TRUE(ReadImageHeader(dir_ / "cut.png").format.empty());
}

TEST_F(ImageIoTest, ExrFloatRoundTripIsExact) {
  std::mt19937 rng(3);
  std::normal_distribution<float> value(0.0f, 1000.0f);
  for (const int channels : {1, 3, 4}) {
    cv::Mat image(29, 41, CV_32FC(channels));
    for (float* p = image.ptr<float>(); p != image.ptr<float>() + image.total() * channels; ++p) {
      *p = value(rng);
    }
    image.at<float>(3, 4) = std::numeric_limits<float>::quiet_NaN();
    image.at<float>(5, 6) = std::numeric_limits<float>::infinity();
    const auto path = dir_ / ("float" + std::to_string(channels) + ".exr");
    WriteExr(path, image, ExrPixel::kFloat);
    const cv::Mat back = ReadExr(path);
    ASSERT_EQ(back.type(), image.type());
    ASSERT_EQ(back.size(), image.size());
    // Bitwise equal, NaN included.
    EXPECT_EQ(std::memcmp(back.data, image.data, image.total() * image.elemSize()), 0);
  }
}

// Half channels round values to the nearest half; values that are already
// halves come back exactly, others within half a unit in the last place.
TEST_F(ImageIoTest, ExrHalfRoundTrip) {
  std::mt19937 rng(4);
  std::uniform_int_distribution<int> mantissa(0, 2047);
  std::uniform_int_distribution<int> exponent(-10, 4);  // <= 2047 * 16 < 65504
  cv::Mat exact(17, 23, CV_32FC3);
  cv::Mat any(17, 23, CV_32FC3);
  std::uniform_real_distribution<float> value(-100.0f, 100.0f);
  for (int i = 0; i < exact.rows * exact.cols * 3; ++i) {
    // m * 2^e with an 11-bit m is representable as a half.
    exact.ptr<float>()[i] = std::ldexp(static_cast<float>(mantissa(rng)), exponent(rng));
    any.ptr<float>()[i] = value(rng);
  }
  WriteExr(dir_ / "exact.exr", exact, ExrPixel::kHalf);
  WriteExr(dir_ / "any.exr", any, ExrPixel::kHalf);
  EXPECT_EQ(cv::norm(ReadExr(dir_ / "exact.exr"), exact, cv::NORM_INF), 0);
  const cv::Mat back = ReadExr(dir_ / "any.exr");
  for (int i = 0; i < any.rows * any.cols * 3; ++i) {
    const float v = any.ptr<float>()[i];
    EXPECT_LE(std::abs(back.ptr<float>()[i] - v), std::abs(v) * (1.0f / 2048) + 1e-7f);
  }
  // Half files are smaller than float files of the same pixels.
  WriteExr(dir_ / "any_float.exr", any, ExrPixel::kFloat);
  EXPECT_LT(std::filesystem::file_size(dir_ / "any.exr"),
            std::filesystem::file_size(dir_ / "any_float.exr"));
}

TEST_F(ImageIoTest, ExrRejectsBadInput) {
  EXPECT_THROW(WriteExr(dir_ / "a.exr", cv::Mat(3, 3, CV_8UC3)), InputError);
  EXPECT_THROW(WriteExr(dir_ / "b.exr", cv::Mat(3, 3, CV_32FC2)), InputError);
  EXPECT_THROW(WriteExr(dir_ / "c.exr", cv::Mat()), InputError);
  EXPECT_THROW(ReadExr(dir_ / "missing.exr"), InputError);
  WriteFileAtomic(dir_ / "garbage.exr", "definitely not an exr file");
  EXPECT_THROW(ReadExr(dir_ / "garbage.exr"), InputError);
}

}  // namespace
}  // namespace hmc
