#include "core/image_io.h"

#include <algorithm>
#include <cstdint>
#include <exception>
#include <fstream>
#include <string>
#include <vector>

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfOutputFile.h>
#include <ImfStdIO.h>
#include <opencv2/imgcodecs.hpp>

#include "core/error.h"
#include "core/file_util.h"

namespace hmc {
namespace {

std::vector<std::string> ExrChannelNames(int channels) {
  switch (channels) {
    case 1: return {"Y"};
    case 3: return {"B", "G", "R"};
    case 4: return {"B", "G", "R", "A"};
    default: return {};
  }
}

}  // namespace

void WritePng(const std::filesystem::path& path, const cv::Mat& image, bool declare_srgb) {
  if (image.empty()) ThrowInputError(path, 0, "cannot write an empty image");
  const int depth = image.depth();
  const int channels = image.channels();
  if ((depth != CV_8U && depth != CV_16U) ||
      (channels != 1 && channels != 3 && channels != 4)) {
    ThrowInputError(path, 0,
                    "PNG needs 8- or 16-bit pixels with 1, 3 or 4 channels "
                    "(got OpenCV type {})",
                    cv::typeToString(image.type()));
  }
  std::vector<uchar> bytes;
  if (!cv::imencode(".png", image, bytes)) {
    ThrowInputError(path, 0, "PNG encoding failed");
  }
  if (declare_srgb && bytes.size() > 33) {
    // An sRGB chunk (rendering intent 0, perceptual) right after IHDR
    // (8-byte signature + 25-byte IHDR chunk), where the PNG specification
    // puts colour-space chunks; its CRC-32 over "sRGB\0" is 0xAECE1CE9.
    static const uchar kSrgb[13] = {0, 0, 0, 1, 's', 'R', 'G', 'B', 0, 0xAE, 0xCE, 0x1C, 0xE9};
    bytes.insert(bytes.begin() + 33, kSrgb, kSrgb + 13);
  }
  WriteFileAtomic(path, std::string_view(
                            reinterpret_cast<const char*>(bytes.data()),
                            bytes.size()));
}

cv::Mat ReadPng(const std::filesystem::path& path) {
  const std::string bytes = ReadFile(path);
  const cv::Mat buffer(1, static_cast<int>(bytes.size()), CV_8U,
                       const_cast<char*>(bytes.data()));
  cv::Mat image = cv::imdecode(buffer, cv::IMREAD_UNCHANGED);
  if (image.empty()) ThrowInputError(path, 0, "not a readable image");
  return image;
}

void WriteExr(const std::filesystem::path& path, const cv::Mat& image,
              ExrPixel pixel) {
  const std::vector<std::string> names = ExrChannelNames(image.channels());
  if (image.empty() || image.depth() != CV_32F || names.empty()) {
    ThrowInputError(path, 0,
                    "OpenEXR output needs a non-empty CV_32F image with 1, 3 "
                    "or 4 channels (got OpenCV type {})",
                    cv::typeToString(image.type()));
  }
  const Imf::PixelType file_type =
      pixel == ExrPixel::kHalf ? Imf::HALF : Imf::FLOAT;
  std::string encoded;
  try {
    Imf::Header header(image.cols, image.rows);
    header.compression() = Imf::ZIP_COMPRESSION;
    // OpenEXR writes a frame buffer of the file's pixel type: halves are
    // converted by OpenCV first (IEEE binary16, round to nearest even).
    cv::Mat pixels = image;
    if (file_type == Imf::HALF) image.convertTo(pixels, CV_16F);
    Imf::FrameBuffer frame_buffer;
    const size_t channel_bytes = pixels.elemSize1();
    const size_t x_stride = channel_bytes * pixels.channels();
    const size_t y_stride = pixels.step[0];
    for (size_t c = 0; c < names.size(); ++c) {
      header.channels().insert(names[c], Imf::Channel(file_type));
      frame_buffer.insert(
          names[c], Imf::Slice(file_type,
                               reinterpret_cast<char*>(pixels.ptr(0)) +
                                   c * channel_bytes,
                               x_stride, y_stride));
    }
    Imf::StdOSStream stream;
    Imf::OutputFile file(stream, header);
    file.setFrameBuffer(frame_buffer);
    file.writePixels(image.rows);
    encoded = stream.str();
  } catch (const std::exception& error) {
    ThrowInputError(path, 0, "OpenEXR encoding failed: {}", error.what());
  }
  WriteFileAtomic(path, encoded);
}

cv::Mat ReadExr(const std::filesystem::path& path) {
  // ReadFile gives the clear "does not exist / cannot open" messages.
  const std::string bytes = ReadFile(path);
  try {
    Imf::StdISStream stream;
    stream.str(bytes);
    Imf::InputFile file(stream);
    const Imf::Header& header = file.header();
    const Imath::Box2i window = header.dataWindow();
    const int width = window.max.x - window.min.x + 1;
    const int height = window.max.y - window.min.y + 1;
    const Imf::ChannelList& channels = header.channels();
    std::vector<std::string> names;
    if (channels.findChannel("R") && channels.findChannel("G") &&
        channels.findChannel("B")) {
      names = ExrChannelNames(channels.findChannel("A") ? 4 : 3);
    } else if (channels.findChannel("Y")) {
      names = ExrChannelNames(1);
    } else {
      ThrowInputError(path, 0,
                      "OpenEXR file has neither R, G, B nor Y channels");
    }
    cv::Mat image(height, width, CV_32FC(static_cast<int>(names.size())),
                  cv::Scalar::all(0));
    Imf::FrameBuffer frame_buffer;
    const size_t x_stride = sizeof(float) * names.size();
    for (size_t c = 0; c < names.size(); ++c) {
      frame_buffer.insert(
          names[c],
          Imf::Slice::Make(Imf::FLOAT, image.ptr<float>(0) + c, window,
                           x_stride, image.step[0]));
    }
    file.setFrameBuffer(frame_buffer);
    file.readPixels(window.min.y, window.max.y);
    return image;
  } catch (const InputError&) {
    throw;
  } catch (const std::exception& error) {
    ThrowInputError(path, 0, "cannot read OpenEXR: {}", error.what());
  }
}

namespace {

uint32_t BigEndian(const unsigned char* p, int bytes) {
  uint32_t v = 0;
  for (int i = 0; i < bytes; ++i) v = (v << 8) | p[i];
  return v;
}

uint32_t Endian(const unsigned char* p, int bytes, bool little) {
  if (!little) return BigEndian(p, bytes);
  uint32_t v = 0;
  for (int i = bytes - 1; i >= 0; --i) v = (v << 8) | p[i];
  return v;
}

// The colour-space chunks of a PNG, which come before its first IDAT: in
// the order of precedence of the PNG specification, sRGB, then iCCP (any
// display profile is near sRGB's curve; one named linear is not), then
// gAMA (the encoding exponent: 0.45455 is sRGB's, 1 linear).
void PngTransfer(const std::vector<unsigned char>& b, ImageHeader* h) {
  std::string iccp;
  double gamma = -1;
  for (size_t at = 8; at + 8 <= b.size();) {
    const size_t length = BigEndian(&b[at], 4);
    const std::string type(b.begin() + at + 4, b.begin() + at + 8);
    if (type == "IDAT" || type == "IEND" || length > b.size()) break;
    const size_t data = at + 8;
    if (type == "sRGB") {
      h->transfer = "srgb";
      h->transfer_why = "PNG sRGB chunk";
      return;
    }
    if (type == "iCCP" && data + length <= b.size()) {
      // The profile's name: Latin-1, NUL-terminated, first in the chunk.
      size_t end = data;
      while (end < data + length && b[end] != 0) ++end;
      iccp.assign(b.begin() + data, b.begin() + end);
      if (iccp.empty()) iccp = "(unnamed)";
    }
    if (type == "gAMA" && length == 4 && data + 4 <= b.size()) {
      gamma = BigEndian(&b[data], 4) / 100000.0;
    }
    at = data + length + 4;
  }
  if (!iccp.empty()) {
    std::string lower = iccp;
    std::transform(lower.begin(), lower.end(), lower.begin(), ::tolower);
    h->transfer = lower.find("linear") != std::string::npos ? "linear" : "srgb";
    h->transfer_why = fmt::format("PNG iCCP profile '{}'", iccp);
    return;
  }
  if (gamma > 0) {
    // Between the two, the nearer one; hmc has no other curve.
    h->transfer = gamma > 0.72 ? "linear" : "srgb";
    h->transfer_why = fmt::format("PNG gAMA {:.5f}", gamma);
  }
}

}  // namespace

ImageHeader ReadImageHeader(const std::filesystem::path& path) {
  ImageHeader h;
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    h.error = "cannot be opened";
    return h;
  }
  // The header lies in the first 64 KiB for every file a camera writes
  // (JPEG's SOF follows the tables; TIFF's first IFD is usually at 8).
  std::vector<unsigned char> b(65536);
  in.read(reinterpret_cast<char*>(b.data()), static_cast<std::streamsize>(b.size()));
  b.resize(static_cast<size_t>(in.gcount()));
  const size_t n = b.size();
  static const unsigned char kPng[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (n >= 8 && std::equal(kPng, kPng + 8, b.begin())) {
    h.format = "PNG";
    if (n < 24 || std::string(b.begin() + 12, b.begin() + 16) != "IHDR") {
      h.error = "PNG header (IHDR) cut short";
      h.format.clear();
      return h;
    }
    h.size = cv::Size(static_cast<int>(std::min<uint32_t>(BigEndian(&b[16], 4), INT32_MAX)),
                      static_cast<int>(std::min<uint32_t>(BigEndian(&b[20], 4), INT32_MAX)));
    PngTransfer(b, &h);
    return h;
  }
  if (n >= 3 && b[0] == 0xff && b[1] == 0xd8 && b[2] == 0xff) {
    // Segments FF xx LEN... up to a start of frame (SOF0..SOF15 but for
    // DHT C4, JPG C8, DAC CC): precision, height, width.
    size_t at = 2;
    while (at + 4 <= n && b[at] == 0xff) {
      const unsigned char marker = b[at + 1];
      if (marker == 0xff) {
        ++at;
        continue;
      }
      const size_t length = BigEndian(&b[at + 2], 2);
      if (marker >= 0xc0 && marker <= 0xcf && marker != 0xc4 && marker != 0xc8 &&
          marker != 0xcc) {
        if (at + 9 > n) break;
        h.format = "JPEG";
        h.transfer = "srgb";
        h.transfer_why = "JPEG (sRGB by convention)";
        h.size = cv::Size(static_cast<int>(BigEndian(&b[at + 7], 2)),
                          static_cast<int>(BigEndian(&b[at + 5], 2)));
        return h;
      }
      if (length < 2) break;
      at += 2 + length;
    }
    h.error = "JPEG header without a frame size in its first 64 KiB";
    return h;
  }
  const bool little = n >= 4 && b[0] == 'I' && b[1] == 'I' && b[2] == 42 && b[3] == 0;
  const bool big = n >= 4 && b[0] == 'M' && b[1] == 'M' && b[2] == 0 && b[3] == 42;
  if (little || big) {
    const size_t ifd = n >= 8 ? Endian(&b[4], 4, little) : n;
    if (ifd + 2 <= n) {
      const size_t entries = Endian(&b[ifd], 2, little);
      long width = -1, height = -1;
      for (size_t e = 0; e < entries && ifd + 2 + 12 * (e + 1) <= n; ++e) {
        const unsigned char* entry = &b[ifd + 2 + 12 * e];
        const uint32_t tag = Endian(entry, 2, little);
        const uint32_t type = Endian(entry + 2, 2, little);
        const uint32_t value = Endian(entry + 8, type == 3 ? 2 : 4, little);  // SHORT or LONG
        if (tag == 256) width = value;
        if (tag == 257) height = value;
      }
      if (width >= 0 && height >= 0) {
        h.format = "TIFF";
        h.size = cv::Size(static_cast<int>(std::min<long>(width, INT32_MAX)),
                          static_cast<int>(std::min<long>(height, INT32_MAX)));
        return h;
      }
    }
    h.error = "TIFF header without an image size in its first 64 KiB";
    return h;
  }
  h.error = n < 8 ? "too short to be an image" : "not a PNG, JPEG or TIFF image";
  return h;
}

}  // namespace hmc
