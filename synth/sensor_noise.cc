#include "synth/sensor_noise.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "core/error.h"
#include "core/parallel.h"
#include "synth/synth_random.h"

namespace hmc {
namespace {

uint64_t Mix(uint64_t x) {
  x += 0x9E3779B97F4A7C15ULL;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ULL;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBULL;
  return x ^ (x >> 31);
}

// Standard normal draws, looked up by a per-pixel hash: sensor noise needs
// a million draws per image, and Box-Muller per pixel cost more than the
// whole shading. 2^16 values (256 KB, cache resident) picked at random per
// pixel are, for a tracker, as good as independent draws.
constexpr int kNormalTableBits = 16;
const std::vector<float>& NormalTable() {
  static const std::vector<float> table = [] {
    std::vector<float> t(size_t{1} << kNormalTableBits);
    SynthRandom rng(0x5eed);
    for (float& v : t) v = static_cast<float>(rng.Normal());
    return t;
  }();
  return table;
}

}  // namespace

cv::Mat RecordSensorImage(const cv::Mat& signal, const cv::Mat& vignette, double read_noise,
                          double shot_noise, uint64_t noise_key, bool srgb) {
  HMC_CHECK(signal.type() == CV_32F);
  HMC_CHECK(vignette.empty() || (vignette.type() == CV_32F && vignette.size() == signal.size()));
  const int width = signal.cols;
  cv::Mat image(signal.rows, width, CV_8U);
  const double read = read_noise, shot = shot_noise;
  const bool vignetting = !vignette.empty();
  const std::vector<float>& normals = NormalTable();
  ParallelFor(0, signal.rows, [&](int64_t y) {
    const float* in = signal.ptr<float>(static_cast<int>(y));
    const float* factor = vignetting ? vignette.ptr<float>(static_cast<int>(y)) : nullptr;
    uint8_t* row = image.ptr<uint8_t>(static_cast<int>(y));
    for (int x = 0; x < width; ++x) {
      const float value = vignetting ? in[x] * factor[x] : in[x];
      double level = 255.0 * value;
      if (read > 0 || shot > 0) {
        // Per-pixel hashed draw: the same noise whatever the thread count.
        const uint64_t h =
            Mix(noise_key * 0xD1B54A32D192ED03ULL + static_cast<uint64_t>(y) * width + x);
        level += std::sqrt(read * read + shot * std::max(level, 0.0)) *
                 normals[h >> (64 - kNormalTableBits)];
      }
      level = std::clamp(level, 0.0, 255.0);
      if (srgb) {
        // IEC 61966-2-1, applied before quantisation as a camera does.
        const double v = level / 255.0;
        level = 255.0 * (v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1 / 2.4) - 0.055);
      }
      row[x] = static_cast<uint8_t>(level + 0.5);
    }
  });
  return image;
}

}  // namespace hmc
