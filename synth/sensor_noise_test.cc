#include "synth/sensor_noise.h"

#include <cmath>

#include <gtest/gtest.h>

namespace hmc {
namespace {

// The sRGB decoding of IEC 61966-2-1 (its own threshold, 0.04045 on the
// encoded side): an independent inverse of the encoder.
double DecodeSrgb(double e) {
  return e <= 0.04045 ? e / 12.92 : std::pow((e + 0.055) / 1.055, 2.4);
}

// `render.transfer: srgb` (issue 44, item 7): without noise each recorded
// level decodes back to the linear signal within half an 8-bit step of the
// encoding, black and full scale stay 0 and 255, and the levels rise with
// the signal.
TEST(SensorNoiseTest, SrgbEncodingDecodesToTheSignal) {
  cv::Mat signal(1, 1001, CV_32F);
  for (int i = 0; i < signal.cols; ++i) signal.at<float>(0, i) = static_cast<float>(i / 1000.0);
  const cv::Mat linear = RecordSensorImage(signal, cv::Mat(), 0, 0, 1, false);
  const cv::Mat srgb = RecordSensorImage(signal, cv::Mat(), 0, 0, 1, true);
  EXPECT_EQ(srgb.at<uint8_t>(0, 0), 0);
  EXPECT_EQ(srgb.at<uint8_t>(0, signal.cols - 1), 255);
  for (int i = 0; i < signal.cols; ++i) {
    const double v = signal.at<float>(0, i);
    const int level = srgb.at<uint8_t>(0, i);
    if (i > 0) {
      EXPECT_GE(level, srgb.at<uint8_t>(0, i - 1));
    }
    // The true encoding lies within half a level of the recorded one.
    EXPECT_LE(DecodeSrgb((level - 0.5) / 255.0), v + 1e-6) << i;
    EXPECT_GE(DecodeSrgb((level + 0.5) / 255.0), v - 1e-6) << i;
    // Darks are lifted (a dark dot reads brighter than in linear values).
    if (v > 0.01 && v < 0.9) {
      EXPECT_GT(level, linear.at<uint8_t>(0, i)) << i;
    }
  }
}

}  // namespace
}  // namespace hmc
