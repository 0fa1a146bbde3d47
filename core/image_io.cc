#include "core/image_io.h"

#include <exception>
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

void WritePng(const std::filesystem::path& path, const cv::Mat& image) {
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

}  // namespace hmc
