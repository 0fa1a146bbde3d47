// The drawing of a named dot on review pictures (`hmc track --overlay`,
// `hmc undistort --tracks`): a green circle and the marker's name.
#pragma once

#include <string>

#include <opencv2/core.hpp>

#include "core/types.h"

namespace hmc {

// bgr: CV_8UC3; pixel in OpenCV pixel centres (sub-pixel circle centre).
void DrawNamedDot(cv::Mat* bgr, const Vec2& pixel, const std::string& name);

}  // namespace hmc
