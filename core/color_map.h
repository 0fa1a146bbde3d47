// Colour maps for scalar fields: heat maps on meshes (render_mesh.h), in
// debug images and in evaluation pictures, with a labelled colour bar.
// Sequential maps come from OpenCV's tables (cv::applyColorMap), sampled at
// 256 levels and interpolated linearly between them.
#pragma once

#include <string>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "core/types.h"

namespace hmc {

enum class ColorMap {
  kViridis,   // perceptually uniform, colour-blind safe: errors, distances
  kInferno,   // perceptually uniform, dark to bright
  kTurbo,     // rainbow-like, high contrast
  kCoolWarm,  // diverging blue - grey - red for signed values (Moreland
              // 2009 "Diverging color maps for scientific visualization":
              // his end points and mid grey, interpolated linearly in RGB)
};

// "viridis", "inferno", "turbo", "coolwarm". Throws InputError otherwise.
ColorMap ParseColorMap(const std::string& name);
std::string ColorMapName(ColorMap map);

// RGB in [0, 1] for t in [0, 1] (clamped). NaN gives mid grey.
Eigen::Vector3d MapColor(ColorMap map, double t);

// Maps values to RGB in [0, 1] with t = (value - lo) / (hi - lo), clamped.
// values: N scalars; returns N x 3. Requires hi > lo.
MatX3d MapScalars(const Eigen::VectorXd& values, double lo, double hi,
                  ColorMap map);

// A heat map of a single-channel CV_32F or CV_64F image: CV_8UC3 (BGR).
// Non-finite pixels get `invalid_bgr` (masked-out areas).
cv::Mat HeatMap(const cv::Mat& values, double lo, double hi, ColorMap map,
                const cv::Scalar& invalid_bgr = cv::Scalar(40, 40, 40));

// A vertical colour bar of `height` px, `hi` at the top and `lo` at the
// bottom, with tick labels and an optional title (units) above: CV_8UC3 on
// the dark grey preview background.
cv::Mat ColorBar(ColorMap map, double lo, double hi, int height,
                 const std::string& title = "");

// `image` (CV_8UC3) with ColorBar(...) appended on its right.
cv::Mat WithColorBar(const cv::Mat& image, ColorMap map, double lo, double hi,
                     const std::string& title = "");

}  // namespace hmc
