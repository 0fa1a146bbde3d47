#include "core/color_map.h"

#include <cmath>
#include <random>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "core/error.h"

namespace hmc {
namespace {

double Luminance(const Eigen::Vector3d& rgb) {
  return 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2];
}

// The sequential maps come from OpenCV's tables: at the 256 levels they
// match cv::applyColorMap exactly.
TEST(ColorMap, MatchesOpenCvTablesAtTheLevels) {
  cv::Mat ramp(1, 256, CV_8UC1);
  for (int i = 0; i < 256; ++i) ramp.at<uchar>(0, i) = static_cast<uchar>(i);
  cv::Mat bgr;
  cv::applyColorMap(ramp, bgr, cv::COLORMAP_VIRIDIS);
  for (int i = 0; i < 256; ++i) {
    const Eigen::Vector3d rgb = MapColor(ColorMap::kViridis, i / 255.0) * 255.0;
    const cv::Vec3b expected = bgr.at<cv::Vec3b>(0, i);
    EXPECT_NEAR(rgb[0], expected[2], 1e-9);
    EXPECT_NEAR(rgb[1], expected[1], 1e-9);
    EXPECT_NEAR(rgb[2], expected[0], 1e-9);
  }
}

TEST(ColorMap, PerceptualMapsBrightenMonotonically) {
  for (ColorMap map : {ColorMap::kViridis, ColorMap::kInferno}) {
    double previous = -1;
    for (int i = 0; i <= 50; ++i) {
      const double l = Luminance(MapColor(map, i / 50.0));
      EXPECT_GT(l, previous - 1e-3) << ColorMapName(map) << " " << i;
      previous = l;
    }
  }
}

TEST(ColorMap, ClampsAndHandlesNaN) {
  std::mt19937 rng(2);
  std::uniform_real_distribution<double> t(0.0, 1.0);
  for (ColorMap map : {ColorMap::kViridis, ColorMap::kInferno, ColorMap::kTurbo,
                       ColorMap::kCoolWarm}) {
    EXPECT_EQ(MapColor(map, -3.0), MapColor(map, 0.0));
    EXPECT_EQ(MapColor(map, 7.0), MapColor(map, 1.0));
    EXPECT_EQ(MapColor(map, NAN), Eigen::Vector3d::Constant(0.5));
    for (int i = 0; i < 100; ++i) {
      const Eigen::Vector3d c = MapColor(map, t(rng));
      EXPECT_GE(c.minCoeff(), 0.0);
      EXPECT_LE(c.maxCoeff(), 1.0);
    }
    EXPECT_EQ(ParseColorMap(ColorMapName(map)), map);
  }
  EXPECT_THROW(ParseColorMap("rainbow"), InputError);
  // Cool-warm: blue end, grey middle, red end.
  const Eigen::Vector3d low = MapColor(ColorMap::kCoolWarm, 0.0);
  const Eigen::Vector3d mid = MapColor(ColorMap::kCoolWarm, 0.5);
  const Eigen::Vector3d high = MapColor(ColorMap::kCoolWarm, 1.0);
  EXPECT_GT(low[2], low[0]);
  EXPECT_GT(high[0], high[2]);
  EXPECT_NEAR(mid[0], mid[2], 0.02);
}

TEST(ColorMap, ScalarsAndHeatMapsAgree) {
  Eigen::VectorXd values(5);
  values << -1, 0, 2.5, 5, 9;
  const MatX3d colors = MapScalars(values, 0, 5, ColorMap::kTurbo);
  ASSERT_EQ(colors.rows(), 5);
  EXPECT_EQ(Eigen::Vector3d(colors.row(0)), MapColor(ColorMap::kTurbo, 0));
  EXPECT_EQ(Eigen::Vector3d(colors.row(2)), MapColor(ColorMap::kTurbo, 0.5));
  EXPECT_EQ(Eigen::Vector3d(colors.row(4)), MapColor(ColorMap::kTurbo, 1));

  cv::Mat field(2, 3, CV_32FC1);
  field.at<float>(0, 0) = 0;
  field.at<float>(0, 1) = 2.5f;
  field.at<float>(0, 2) = 5;
  field.at<float>(1, 0) = NAN;
  field.at<float>(1, 1) = INFINITY;
  field.at<float>(1, 2) = 100;
  const cv::Mat heat = HeatMap(field, 0, 5, ColorMap::kTurbo, cv::Scalar(1, 2, 3));
  ASSERT_EQ(heat.type(), CV_8UC3);
  const Eigen::Vector3d half = MapColor(ColorMap::kTurbo, 0.5) * 255.0;
  const cv::Vec3b at = heat.at<cv::Vec3b>(0, 1);
  EXPECT_NEAR(at[2], half[0], 0.5001);
  EXPECT_NEAR(at[0], half[2], 0.5001);
  EXPECT_EQ(heat.at<cv::Vec3b>(1, 0), cv::Vec3b(1, 2, 3));
  EXPECT_EQ(heat.at<cv::Vec3b>(1, 1), cv::Vec3b(1, 2, 3));
  EXPECT_EQ(heat.at<cv::Vec3b>(1, 2), heat.at<cv::Vec3b>(0, 2));
  EXPECT_THROW(HeatMap(cv::Mat(2, 2, CV_8UC1), 0, 1, ColorMap::kTurbo),
               InputError);
}

// The bar runs from lo at the bottom to hi at the top.
TEST(ColorMap, ColorBarOrientation) {
  const cv::Mat image(200, 120, CV_8UC3, cv::Scalar(0, 0, 0));
  const cv::Mat out = WithColorBar(image, ColorMap::kCoolWarm, -2, 2, "mm");
  ASSERT_EQ(out.rows, 200);
  ASSERT_GT(out.cols, 120);
  const cv::Vec3b top = out.at<cv::Vec3b>(40, 120 + 12);
  const cv::Vec3b bottom = out.at<cv::Vec3b>(185, 120 + 12);
  EXPECT_GT(top[2], top[0]);        // red (hi) at the top
  EXPECT_GT(bottom[0], bottom[2]);  // blue (lo) at the bottom
}

}  // namespace
}  // namespace hmc
