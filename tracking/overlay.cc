#include "tracking/overlay.h"

#include <cmath>

#include <opencv2/imgproc.hpp>

namespace hmc {

void DrawNamedDot(cv::Mat* bgr, const Vec2& pixel, const std::string& name) {
  const int shift = 4;
  const cv::Point centre(static_cast<int>(std::lround(pixel.x() * (1 << shift))),
                         static_cast<int>(std::lround(pixel.y() * (1 << shift))));
  cv::circle(*bgr, centre, 5 << shift, cv::Scalar(60, 220, 60), 1, cv::LINE_AA, shift);
  cv::putText(*bgr, name,
              cv::Point(static_cast<int>(pixel.x()) + 6, static_cast<int>(pixel.y()) - 4),
              cv::FONT_HERSHEY_PLAIN, 0.7, cv::Scalar(80, 230, 255), 1, cv::LINE_AA);
}

}  // namespace hmc
