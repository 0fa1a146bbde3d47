// Image files: 8/16-bit pictures as PNG (OpenCV codec) and float images
// (heat maps, UV-space displacement maps) as OpenEXR. Writes are atomic
// (core/file_util.h): the image is encoded in memory, then written to a
// temporary file and renamed. Format notes: docs/formats.md, "Images".
#pragma once

#include <filesystem>
#include <string>

#include <opencv2/core.hpp>

namespace hmc {

// Writes an 8- or 16-bit image with 1 (grey), 3 (BGR) or 4 (BGRA)
// channels as PNG. Lossless: ReadPng returns the same pixels.
// Throws InputError naming `path` if the image is empty or of another type,
// or the file cannot be written. With `declare_srgb` the file carries an
// sRGB chunk (its values are sRGB-encoded, as a camera's PNG says so;
// docs/formats.md, "Footage input").
void WritePng(const std::filesystem::path& path, const cv::Mat& image,
              bool declare_srgb = false);

// Reads a PNG (or any format OpenCV decodes) unchanged: depth and channel
// count as stored. Throws InputError naming `path` if it cannot.
cv::Mat ReadPng(const std::filesystem::path& path);

// What an image file's header declares, read without decoding the pixels
// (a 20000 x 20000 PNG of zeros is 2 MB on disk and 2.4 GB decoded:
// docs/reliability.md). `format` is "" when the file is none of PNG, JPEG
// or TIFF, or its header is cut short; then `error` says why.
// `transfer` is what the file says of its values' encoding: "srgb"
// (PNG sRGB or iCCP chunk, a PNG gAMA near 1/2.2, any JPEG), "linear" (PNG
// gAMA near 1, an iCCP profile named linear) or "" (not stated: a PNG
// without those chunks, TIFF); `transfer_why` names the evidence.
struct ImageHeader {
  std::string format;  // "PNG", "JPEG", "TIFF"
  cv::Size size;
  std::string error;
  std::string transfer;      // "srgb", "linear" or "" (not stated)
  std::string transfer_why;  // "PNG sRGB chunk", "PNG gAMA 0.45455", ...
};
ImageHeader ReadImageHeader(const std::filesystem::path& path);

enum class ExrPixel {
  kHalf,   // 16-bit float: 11 bits of mantissa, enough for pictures
  kFloat,  // 32-bit float: exact for CV_32F data (measurements, maps)
};

// Writes a CV_32F image with 1, 3 or 4 channels as a scanline OpenEXR file
// (ZIP compression). Channel names: 1 -> "Y"; 3 -> "B", "G", "R" (OpenCV
// order, so viewers show the colours right); 4 -> "B", "G", "R", "A".
// Non-finite values are stored as they are. With kHalf, values are rounded
// to the nearest half.
void WriteExr(const std::filesystem::path& path, const cv::Mat& image,
              ExrPixel pixel = ExrPixel::kFloat);

// Reads an OpenEXR file written by WriteExr (or any file whose channels are
// "Y", or "R", "G", "B" with optional "A") into CV_32FC1/C3/C4, channel
// order as WriteExr takes it. Missing pixels of the data window are 0.
// Throws InputError naming `path` if it cannot.
cv::Mat ReadExr(const std::filesystem::path& path);

}  // namespace hmc
