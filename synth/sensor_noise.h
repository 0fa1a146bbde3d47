// The camera's sensor for the footage renderer (synth/footage.h,
// docs/footage.md): vignetting, read and shot noise and 8-bit quantisation
// of a linear radiance image.
#pragma once

#include <cstdint>

#include <opencv2/core.hpp>

namespace hmc {

// signal: CV_32F linear radiance (1 = full scale); vignette: CV_32F factor
// of the same size, or empty for none. Each pixel's level is 255 * signal *
// vignette plus a normal draw of variance read^2 + shot * level, rounded
// and clamped to 8 bits. The draw is hashed from (noise_key, pixel), so the
// image is the same whatever the thread count; noise_key must differ per
// frame and camera. With `srgb` the clamped level is encoded with the sRGB
// curve (IEC 61966-2-1) before rounding, as a camera writing sRGB does.
cv::Mat RecordSensorImage(const cv::Mat& signal, const cv::Mat& vignette, double read_noise,
                          double shot_noise, uint64_t noise_key, bool srgb = false);

}  // namespace hmc
