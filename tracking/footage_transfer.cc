// The footage's values: the colour transfer a video states, sRGB to linear
// light, and the grey views of the reader's images (tracking/footage_reader.h).
#include "tracking/footage_reader.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <functional>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "core/error.h"

namespace hmc {

namespace fs = std::filesystem;

namespace {

// The transfer characteristic of an ISO BMFF video (.mp4, .mov): the
// `colr` box ('nclx' or QuickTime's 'nclc') of its first visual sample
// entry, under moov/trak/mdia/minf/stbl/stsd; its codes are those of
// ITU-T H.273. 0 when absent. Only box headers are read outside `moov`
// (which may sit at the end of a large file).
int IsoBmffTransferCode(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return 0;
  auto be = [](const unsigned char* p, int n) {
    uint64_t v = 0;
    for (int i = 0; i < n; ++i) v = (v << 8) | p[i];
    return v;
  };
  // Top level: find moov by its header.
  std::vector<unsigned char> moov;
  for (uint64_t at = 0;;) {
    unsigned char h[16];
    in.seekg(static_cast<std::streamoff>(at));
    if (!in.read(reinterpret_cast<char*>(h), 8)) return 0;
    uint64_t size = be(h, 4);
    uint64_t header = 8;
    if (size == 1) {
      if (!in.read(reinterpret_cast<char*>(h + 8), 8)) return 0;
      size = be(h + 8, 8);
      header = 16;
    }
    if (size < header) return 0;  // 0 = "to the end of the file": not moov's way
    if (std::string(h + 4, h + 8) == "moov") {
      if (size > (64u << 20)) return 0;
      moov.resize(size - header);
      if (!in.read(reinterpret_cast<char*>(moov.data()), static_cast<std::streamsize>(moov.size()))) {
        return 0;
      }
      break;
    }
    at += size;
  }
  // Inside moov: descend into the containers on the path to colr. A visual
  // sample entry's children follow its 78 bytes of fields.
  std::function<int(size_t, size_t, int)> walk = [&](size_t begin, size_t end, int depth) {
    for (size_t at = begin; at + 8 <= end;) {
      const uint64_t size = be(&moov[at], 4);
      if (size < 8 || at + size > end) return 0;
      const std::string type(moov.begin() + at + 4, moov.begin() + at + 8);
      const size_t body = at + 8;
      if (type == "colr" && size >= 18) {
        const std::string kind(moov.begin() + body, moov.begin() + body + 4);
        if (kind == "nclx" || kind == "nclc") return static_cast<int>(be(&moov[body + 6], 2));
      }
      int found = 0;
      if (depth < 8) {
        if (type == "trak" || type == "mdia" || type == "minf" || type == "stbl") {
          found = walk(body, at + size, depth + 1);
        } else if (type == "stsd" && size >= 16) {
          found = walk(body + 8, at + size, depth + 1);  // version, flags, entry count
        } else if (depth == 5 && size >= 8 + 78) {
          found = walk(body + 78, at + size, depth + 1);  // a visual sample entry
        }
      }
      if (found) return found;
      at += size;
    }
    return 0;
  };
  return walk(0, moov.size(), 0);
}


// The sRGB decoding curve (IEC 61966-2-1) of a value in [0, 1].
double SrgbToLinear(double v) {
  return v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4);
}

// Level -> linear 16-bit level, for every level of `levels` (256 or 65536).
std::vector<uint16_t> SrgbTable(int levels) {
  std::vector<uint16_t> table(levels);
  for (int i = 0; i < levels; ++i) {
    table[i] = static_cast<uint16_t>(std::lround(65535 * SrgbToLinear(i / (levels - 1.0))));
  }
  return table;
}

}  // namespace

std::string VideoTransfer(const fs::path& path, std::string* why) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
  if (ext != ".mp4" && ext != ".mov") {
    *why = fmt::format("the colour transfer of a {} video is not read", ext);
    return "";
  }
  const int code = IsoBmffTransferCode(path);
  // H.273: 1 BT.709, 6 BT.601, 13 sRGB, 14/15 BT.2020 (the BT.709 curve);
  // 8 linear; 2 unspecified.
  if (code == 1 || code == 6 || code == 13 || code == 14 || code == 15) {
    *why = fmt::format("{}'s colr box: transfer {}", path.filename().string(), code);
    return "srgb";
  }
  if (code == 8) {
    *why = fmt::format("{}'s colr box: transfer 8 (linear)", path.filename().string());
    return "linear";
  }
  *why = code == 0 ? fmt::format("no colour transfer in {}'s colr box", path.filename().string())
                   : fmt::format("{}'s colr box: transfer {}, a curve hmc does not invert",
                                 path.filename().string(), code);
  return "";
}

cv::Mat SrgbToLinear16(const cv::Mat& image) {
  static const std::vector<uint16_t> table8 = SrgbTable(256);
  static const std::vector<uint16_t> table16 = SrgbTable(65536);
  HMC_CHECK(image.channels() == 1 && (image.depth() == CV_8U || image.depth() == CV_16U));
  cv::Mat out(image.size(), CV_16U);
  const bool eight = image.depth() == CV_8U;
  const uint16_t* table = eight ? table8.data() : table16.data();
  for (int y = 0; y < image.rows; ++y) {
    uint16_t* o = out.ptr<uint16_t>(y);
    if (eight) {
      const uint8_t* i = image.ptr<uint8_t>(y);
      for (int x = 0; x < image.cols; ++x) o[x] = table[i[x]];
    } else {
      const uint16_t* i = image.ptr<uint16_t>(y);
      for (int x = 0; x < image.cols; ++x) o[x] = table[i[x]];
    }
  }
  return out;
}

cv::Mat ToGrey8(const cv::Mat& image) {
  if (image.depth() == CV_8U) return image;
  cv::Mat out;
  image.convertTo(out, CV_8U, 1.0 / 257.0);
  return out;
}

cv::Mat ToGreyFloat(const cv::Mat& image) {
  cv::Mat out;
  image.convertTo(out, CV_32F, image.depth() == CV_16U ? 1.0 / 65535.0 : 1.0 / 255.0);
  return out;
}

}  // namespace hmc
