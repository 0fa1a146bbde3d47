#include "core/color_map.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

#include "core/error.h"

namespace hmc {
namespace {

constexpr int kLevels = 256;
using Table = std::array<Eigen::Vector3d, kLevels>;  // RGB in [0, 1]

Table OpenCvTable(cv::ColormapTypes type) {
  cv::Mat ramp(1, kLevels, CV_8UC1);
  for (int i = 0; i < kLevels; ++i) ramp.at<uchar>(0, i) = static_cast<uchar>(i);
  cv::Mat bgr;
  cv::applyColorMap(ramp, bgr, type);
  Table table;
  for (int i = 0; i < kLevels; ++i) {
    const cv::Vec3b c = bgr.at<cv::Vec3b>(0, i);
    table[i] = Eigen::Vector3d(c[2], c[1], c[0]) / 255.0;
  }
  return table;
}

Table CoolWarmTable() {
  const Eigen::Vector3d blue(59, 76, 192);
  const Eigen::Vector3d grey(221, 221, 221);
  const Eigen::Vector3d red(180, 4, 38);
  Table table;
  for (int i = 0; i < kLevels; ++i) {
    const double t = static_cast<double>(i) / (kLevels - 1);
    table[i] = (t < 0.5 ? blue + (grey - blue) * (2 * t)
                        : grey + (red - grey) * (2 * t - 1)) /
               255.0;
  }
  return table;
}

const Table& TableOf(ColorMap map) {
  static const Table viridis = OpenCvTable(cv::COLORMAP_VIRIDIS);
  static const Table inferno = OpenCvTable(cv::COLORMAP_INFERNO);
  static const Table turbo = OpenCvTable(cv::COLORMAP_TURBO);
  static const Table coolwarm = CoolWarmTable();
  switch (map) {
    case ColorMap::kViridis: return viridis;
    case ColorMap::kInferno: return inferno;
    case ColorMap::kTurbo: return turbo;
    case ColorMap::kCoolWarm: return coolwarm;
  }
  return viridis;
}

cv::Vec3b ToBgr8(const Eigen::Vector3d& rgb) {
  return cv::Vec3b(cv::saturate_cast<uchar>(rgb[2] * 255.0),
                   cv::saturate_cast<uchar>(rgb[1] * 255.0),
                   cv::saturate_cast<uchar>(rgb[0] * 255.0));
}

}  // namespace

ColorMap ParseColorMap(const std::string& name) {
  for (ColorMap map : {ColorMap::kViridis, ColorMap::kInferno, ColorMap::kTurbo,
                       ColorMap::kCoolWarm}) {
    if (ColorMapName(map) == name) return map;
  }
  throw InputError(fmt::format(
      "unknown colour map '{}' (viridis, inferno, turbo, coolwarm)", name));
}

std::string ColorMapName(ColorMap map) {
  switch (map) {
    case ColorMap::kViridis: return "viridis";
    case ColorMap::kInferno: return "inferno";
    case ColorMap::kTurbo: return "turbo";
    case ColorMap::kCoolWarm: return "coolwarm";
  }
  return "viridis";
}

Eigen::Vector3d MapColor(ColorMap map, double t) {
  if (std::isnan(t)) return Eigen::Vector3d::Constant(0.5);
  const Table& table = TableOf(map);
  const double x = std::clamp(t, 0.0, 1.0) * (kLevels - 1);
  const int i = std::min(static_cast<int>(x), kLevels - 2);
  const double f = x - i;
  return (1.0 - f) * table[i] + f * table[i + 1];
}

MatX3d MapScalars(const Eigen::VectorXd& values, double lo, double hi,
                  ColorMap map) {
  HMC_CHECK(hi > lo);
  MatX3d colors(values.size(), 3);
  for (Eigen::Index i = 0; i < values.size(); ++i) {
    colors.row(i) = MapColor(map, (values[i] - lo) / (hi - lo)).transpose();
  }
  return colors;
}

cv::Mat HeatMap(const cv::Mat& values, double lo, double hi, ColorMap map,
                const cv::Scalar& invalid_bgr) {
  if (values.channels() != 1 ||
      (values.depth() != CV_32F && values.depth() != CV_64F)) {
    throw InputError("HeatMap needs a single-channel float image, got " +
                     cv::typeToString(values.type()));
  }
  HMC_CHECK(hi > lo);
  cv::Mat as_double;
  values.convertTo(as_double, CV_64F);
  cv::Mat image(values.size(), CV_8UC3);
  const cv::Vec3b invalid(cv::saturate_cast<uchar>(invalid_bgr[0]),
                          cv::saturate_cast<uchar>(invalid_bgr[1]),
                          cv::saturate_cast<uchar>(invalid_bgr[2]));
  for (int y = 0; y < image.rows; ++y) {
    for (int x = 0; x < image.cols; ++x) {
      const double v = as_double.at<double>(y, x);
      image.at<cv::Vec3b>(y, x) =
          std::isfinite(v) ? ToBgr8(MapColor(map, (v - lo) / (hi - lo)))
                           : invalid;
    }
  }
  return image;
}

cv::Mat ColorBar(ColorMap map, double lo, double hi, int height,
                 const std::string& title) {
  constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;
  constexpr double kScale = 0.4;
  constexpr int kTicks = 5;
  constexpr int kBarWidth = 18;
  constexpr int kMargin = 8;
  const cv::Scalar text_color(230, 230, 230);
  std::vector<std::string> labels;
  int label_width = 0;
  int baseline = 0;
  for (int i = 0; i < kTicks; ++i) {
    labels.push_back(fmt::format("{:.3g}", lo + (hi - lo) * i / (kTicks - 1)));
    label_width = std::max(
        label_width, cv::getTextSize(labels.back(), kFont, kScale, 1, &baseline).width);
  }
  const int title_width =
      title.empty() ? 0 : cv::getTextSize(title, kFont, kScale, 1, &baseline).width;
  const int width = std::max(2 * kMargin + kBarWidth + 6 + label_width,
                             2 * kMargin + title_width);
  cv::Mat bar(std::max(height, 60), width, CV_8UC3, cv::Scalar(38, 38, 38));
  const int top = title.empty() ? 10 : 28;
  const int bottom = bar.rows - 10;
  if (!title.empty()) {
    cv::putText(bar, title, cv::Point(kMargin, 16), kFont, kScale, text_color,
                1, cv::LINE_AA);
  }
  for (int y = top; y <= bottom; ++y) {
    const double t = static_cast<double>(bottom - y) / std::max(1, bottom - top);
    cv::line(bar, cv::Point(kMargin, y), cv::Point(kMargin + kBarWidth - 1, y),
             cv::Scalar(ToBgr8(MapColor(map, t))), 1);
  }
  for (int i = 0; i < kTicks; ++i) {
    const int y = bottom - (bottom - top) * i / (kTicks - 1);
    cv::line(bar, cv::Point(kMargin + kBarWidth, y),
             cv::Point(kMargin + kBarWidth + 3, y), text_color, 1);
    cv::putText(bar, labels[i], cv::Point(kMargin + kBarWidth + 6, y + 4),
                kFont, kScale, text_color, 1, cv::LINE_AA);
  }
  return bar;
}

cv::Mat WithColorBar(const cv::Mat& image, ColorMap map, double lo, double hi,
                     const std::string& title) {
  HMC_CHECK(image.type() == CV_8UC3);
  cv::Mat bar = ColorBar(map, lo, hi, image.rows, title);
  if (bar.rows != image.rows) {
    cv::Mat padded(bar.rows, image.cols, CV_8UC3, cv::Scalar(38, 38, 38));
    image.copyTo(padded(cv::Rect(0, 0, image.cols, image.rows)));
    cv::Mat out;
    cv::hconcat(padded, bar, out);
    return out;
  }
  cv::Mat out;
  cv::hconcat(image, bar, out);
  return out;
}

}  // namespace hmc
