// Each camera's footage source: an image folder or a video through FFmpeg
// (tracking/footage_sources.h).
#include "tracking/footage_sources.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <optional>
#include <system_error>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include "core/error.h"
#include "core/file_util.h"
#include "core/image_io.h"
#include "core/text.h"
#include "core/yaml_values.h"
#include "tracking/footage_reader.h"

namespace hmc {

namespace fs = std::filesystem;

namespace {

bool IsImageFile(const fs::path& p) {
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
  return ext == ".png" || ext == ".tif" || ext == ".tiff" || ext == ".jpg" ||
         ext == ".jpeg";
}

bool IsVideoFile(const fs::path& p) {
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
  return ext == ".mkv" || ext == ".mov" || ext == ".mp4" || ext == ".avi" ||
         ext == ".mxf" || ext == ".webm";
}

// Grey, depth kept (8 or 16 bit). Colour is converted with OpenCV's
// luminance weights; other depths are refused by the caller.
cv::Mat ToGrey(const cv::Mat& image) {
  if (image.channels() == 1) return image;
  cv::Mat grey;
  cv::cvtColor(image, grey,
               image.channels() == 4 ? cv::COLOR_BGRA2GRAY : cv::COLOR_BGR2GRAY);
  return grey;
}

// The frame number at the end of a file stem: "frame_000017" -> 17.
std::optional<long long> TrailingNumber(const std::string& stem) {
  size_t end = stem.size();
  size_t begin = end;
  while (begin > 0 && std::isdigit(static_cast<unsigned char>(stem[begin - 1]))) --begin;
  if (begin == end || end - begin > 9) return std::nullopt;
  long long n = 0;
  if (!ParseInteger(std::string_view(stem).substr(begin, end - begin), &n)) return std::nullopt;
  return n;
}

// A video through FFmpeg. Frames are numbered by their timestamps, so a
// frame FFmpeg cannot decode, and skips, leaves a gap instead of shifting
// every later frame.
class VideoSource : public CameraSource {
 public:
  explicit VideoSource(const fs::path& path) : path_(path) {
    // FFmpeg opens a still image under any name as a one-frame "video" of
    // unknown length: refused by its header (docs/reliability.md).
    const ImageHeader still = ReadImageHeader(path);
    if (!still.format.empty()) {
      ThrowInputError(path, 0,
                      "not a video but a {} image (an image sequence is a folder of numbered "
                      "images)",
                      still.format);
    }
    if (!capture_.open(path.string(), cv::CAP_FFMPEG) || !capture_.isOpened()) {
      ThrowInputError(path, 0, "cannot open as a video (FFmpeg)");
    }
    // Keep 16-bit sources 16-bit and grey sources grey where the backend
    // allows it.
    capture_.set(cv::CAP_PROP_CONVERT_RGB, 0);
    const double count = capture_.get(cv::CAP_PROP_FRAME_COUNT);
    const double fps = capture_.get(cv::CAP_PROP_FPS);
    fps_ = std::isfinite(fps) && fps > 0 && fps < 10000 ? fps : 0;
    declared_frames_ = std::isfinite(count) && count > 0 ? static_cast<int>(std::lround(count)) : 0;
    if (!Advance()) ThrowInputError(path, 0, "no frame of the video decodes");
    size_ = cv::Size(static_cast<int>(capture_.get(cv::CAP_PROP_FRAME_WIDTH)),
                     static_cast<int>(capture_.get(cv::CAP_PROP_FRAME_HEIGHT)));
    first_ = pending_frame_;
  }
  cv::Size size() const override { return size_; }
  int first() const override { return first_; }
  int last() const override {
    return std::max(declared_frames_ > 0 ? declared_frames_ : INT_MAX - 1, pending_frame_);
  }
  double fps() const override { return fps_; }
  // OpenCV 4.6 does not expose the stream's colour transfer (color_trc):
  // an .mp4 or .mov says it in its colr box, read here; other containers
  // (.mkv, .avi, ...) are not read.
  std::string StatedTransfer(std::string* why) const override {
    return VideoTransfer(path_, why);
  }
  cv::Mat Read(int frame, std::string* error) override {
    while (!ended_ && pending_frame_ < frame) Advance();
    if (!ended_ && pending_frame_ == frame) {
      cv::Mat out = Retrieve();
      Advance();
      if (out.empty()) {
        *error = "the frame does not decode";
        return {};
      }
      if (out.size() != size_) {
        *error = fmt::format("decoded size {}x{} differs from the video's {}x{}", out.cols,
                             out.rows, size_.width, size_.height);
        return {};
      }
      return out;
    }
    // The next picture's timestamp is later: the video holds no picture of
    // this time (a recorder that dropped frames, variable frame rate).
    *error = !ended_ && pending_frame_ > frame
                 ? "the video has no picture at this frame's time (dropped by the recorder, "
                   "or damaged)"
                 : "the frame does not decode";
    return {};
  }
  void SkipTo(int frame) override {
    const int gap = frame - pending_frame_;
    if (ended_ || gap <= 0) return;
    // A seek decodes from the keyframe before the target (OpenCV's FFmpeg
    // backend also backs up 16 frames): cheaper than decoding `gap` frames
    // only for sparse samples of a long video, by how much depends on the
    // codec's keyframe spacing, which the container does not tell. So the
    // first seek is tried for any gap above kMinSeekGap and timed; later
    // ones are taken when the gap's frames would take longer to decode.
    if (gap > kMinSeekGap && (seek_seconds_ < 0 || gap * decode_seconds_ > seek_seconds_)) {
      if (Seek(frame)) return;
    }
    while (!ended_ && pending_frame_ < frame) Advance();
  }
  bool EndedBefore(int frame) const override {
    return frame > last() || (ended_ && frame > last_decoded_);
  }
  std::vector<std::string> warnings() const override {
    std::vector<std::string> out;
    if (ended_ && declared_frames_ > 0 && last_decoded_ < declared_frames_) {
      out.push_back(fmt::format("{}: declares {} frames, frames after {} do not decode "
                                "(truncated?)",
                                path_.string(), declared_frames_, last_decoded_));
    }
    return out;
  }

 private:
  static constexpr int kMinSeekGap = 48;

  // Positions the video so that the next decoded frame is `frame`, by
  // seeking (cv::CAP_PROP_POS_FRAMES counts from 0). The landing frame is
  // named by its timestamp like every other; a seek that lands past
  // `frame` or fails is undone by reopening the video and decoding up to
  // it. Returns false when it fell back to that.
  bool Seek(int frame) {
    const auto start = std::chrono::steady_clock::now();
    bool ok = false;
    try {
      ok = capture_.set(cv::CAP_PROP_POS_FRAMES, frame - 1);
    } catch (const cv::Exception& e) {
      spdlog::debug("{}: seek: {}", path_.string(), e.what());
    }
    ok = ok && Advance() && pending_frame_ <= frame;
    seek_seconds_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (ok) {
      while (!ended_ && pending_frame_ < frame) Advance();
      return true;
    }
    spdlog::debug("{}: seeking to frame {} failed; decoding up to it", path_.string(), frame);
    seek_seconds_ = std::numeric_limits<double>::infinity();  // do not seek again
    capture_.release();
    if (!capture_.open(path_.string(), cv::CAP_FFMPEG) || !capture_.isOpened()) {
      ended_ = true;
      return false;
    }
    capture_.set(cv::CAP_PROP_CONVERT_RGB, 0);
    pending_frame_ = 0;
    last_decoded_ = 0;
    ended_ = false;
    Advance();
    while (!ended_ && pending_frame_ < frame) Advance();
    return false;
  }

  // Decodes the next frame (cv::VideoCapture::grab: not yet converted to
  // an image, see Retrieve) and numbers it; false (ended_) at the end.
  bool Advance() {
    bool got = false;
    const auto start = std::chrono::steady_clock::now();
    try {
      got = capture_.grab();
    } catch (const cv::Exception& e) {
      spdlog::warn("{}: {}", path_.string(), e.what());
    }
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    decode_seconds_ = decoded_ == 0 ? seconds : 0.9 * decode_seconds_ + 0.1 * seconds;
    ++decoded_;
    if (!got) {
      ended_ = true;
      return false;
    }
    // The decoded picture's timestamp (ms from the stream's start, from its
    // pts) names the frame; OpenCV's CAP_PROP_POS_FRAMES only counts reads.
    const double ms = capture_.get(cv::CAP_PROP_POS_MSEC);
    int number = last_decoded_ + 1;
    if (fps_ > 0 && std::isfinite(ms) && ms >= 0 && (ms > 0 || last_decoded_ == 0)) {
      number = static_cast<int>(std::lround(ms * fps_ / 1000.0)) + 1;
    }
    if (number <= last_decoded_) number = last_decoded_ + 1;  // never go back
    pending_frame_ = number;
    last_decoded_ = number;
    return true;
  }

  // The image of the frame Advance decoded last (empty if it cannot be
  // converted).
  // OpenCV's FFmpeg backend hands out BGR (converted by swscale; grey
  // footage comes back as three equal channels): raw_ keeps that buffer
  // from frame to frame instead of faulting in fresh pages for it.
  cv::Mat Retrieve() {
    try {
      if (!capture_.retrieve(raw_) || raw_.empty()) return {};
    } catch (const cv::Exception& e) {
      spdlog::warn("{}: {}", path_.string(), e.what());
      return {};
    }
    if (raw_.depth() != CV_8U && raw_.depth() != CV_16U) {
      cv::Mat converted;
      raw_.convertTo(converted, CV_8U);
      return ToGrey(converted);
    }
    const cv::Mat grey = ToGrey(raw_);
    return grey.data == raw_.data ? grey.clone() : grey;
  }

  fs::path path_;
  cv::VideoCapture capture_;
  cv::Size size_;
  cv::Mat raw_;  // the last retrieved picture, as the backend gives it
  int pending_frame_ = 0;
  int first_ = 1;
  int last_decoded_ = 0;
  int declared_frames_ = 0;
  double fps_ = 0;  // frames per second, 0 if unknown (then frames are counted)
  bool ended_ = false;
  // What a frame's decode and the last seek took (s; a seek not yet tried:
  // negative), for SkipTo's choice between them.
  double decode_seconds_ = 0;
  int64_t decoded_ = 0;
  double seek_seconds_ = -1;
};

}  // namespace

ImageFolderSource::ImageFolderSource(const fs::path& dir) : dir_(dir) {
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    // Hidden files, among them macOS's AppleDouble `._frame_000001.png`
    // beside every file copied from a Mac: not frames.
    const std::string name = it->path().filename().string();
    if (name.empty() || name.front() == '.') continue;
    if (!it->is_regular_file(ec) || !IsImageFile(it->path())) continue;
    const std::optional<long long> n = TrailingNumber(it->path().stem().string());
    if (!n) continue;
    const auto [pos, inserted] = numbered_.emplace(*n, it->path());
    if (!inserted) {
      ThrowInputError(dir, 0, "two images carry frame number {}: {} and {}", *n,
                      pos->second.filename().string(), it->path().filename().string());
    }
  }
  if (ec) ThrowInputError(dir, 0, "cannot list the image folder: {}", ec.message());
  if (numbered_.empty()) {
    ThrowInputError(dir, 0, "no numbered images (PNG, TIFF, JPEG) in the folder");
  }
}

void ImageFolderSource::SetBase(long long base, long long first_frame, const cv::Size& expected) {
  for (const auto& [n, path] : numbered_) {
    files_.emplace(static_cast<int>(n - base + first_frame), path);
  }
  std::vector<cv::Size> sizes;
  std::string first_error;
  for (auto it = files_.begin(); it != files_.end() && sizes.size() < 3; ++it) {
    const ImageHeader h = ReadImageHeader(it->second);
    if (!h.format.empty()) {
      sizes.push_back(h.size);
    } else if (first_error.empty()) {
      first_error = fmt::format("{}: {}", it->second.string(), h.error);
    }
  }
  if (sizes.empty()) ThrowInputError(dir_, 0, "no readable image header: {}", first_error);
  size_ = sizes[0];
  for (const cv::Size& s : sizes) {
    const long shared = std::count(sizes.begin(), sizes.end(), s);
    if (s == expected || shared * 2 > static_cast<long>(sizes.size())) {
      size_ = s;
      if (s == expected) break;
    }
  }
  const int max_side = yaml_values::kMaxImageSide;
  if (size_.width > max_side || size_.height > max_side || size_.area() <= 0) {
    ThrowInputError(files_.begin()->second, 0, "declares {}x{} pixels, beyond any camera's",
                    size_.width, size_.height);
  }
}

std::string ImageFolderSource::StatedTransfer(std::string* why) const {
  const fs::path& file = numbered_.begin()->second;
  const ImageHeader h = ReadImageHeader(file);
  *why = h.transfer.empty() ? fmt::format("not stated in {}", file.filename().string())
                            : fmt::format("{} in {}", h.transfer_why, file.filename().string());
  return h.transfer;
}

cv::Mat ImageFolderSource::Read(int frame, std::string* error) {
  const auto it = files_.find(frame);
  if (it == files_.end()) {
    *error = "no image file for this frame";
    return {};
  }
  // The header first: a file of another size (a decompression bomb
  // among them) is refused before a pixel is decoded.
  const ImageHeader h = ReadImageHeader(it->second);
  if (h.format.empty()) {
    *error = fmt::format("{}: {}", it->second.string(), h.error);
    return {};
  }
  if (h.size != size_) {
    *error = fmt::format("{} is {}x{}, the sequence is {}x{}", it->second.string(),
                         h.size.width, h.size.height, size_.width, size_.height);
    return {};
  }
  cv::Mat image = Decode(it->second, error);
  if (!image.empty() && image.size() != size_) {
    *error = fmt::format("{} is {}x{}, the sequence is {}x{}", it->second.string(),
                         image.cols, image.rows, size_.width, size_.height);
    return {};
  }
  return image;
}

cv::Mat ImageFolderSource::Decode(const fs::path& path, std::string* error) {
  cv::Mat image;
  try {
    image = cv::imread(path.string(), cv::IMREAD_ANYDEPTH | cv::IMREAD_ANYCOLOR);
  } catch (const cv::Exception& e) {
    *error = fmt::format("{}: {}", path.string(), e.what());
    return {};
  }
  if (image.empty()) {
    *error = fmt::format("{} cannot be decoded", path.string());
    return {};
  }
  if (image.depth() != CV_8U && image.depth() != CV_16U) {
    *error = fmt::format("{} is neither 8 nor 16 bit", path.string());
    return {};
  }
  return ToGrey(image);
}

fs::path FindSource(const fs::path& shot, const std::string& name,
                    const std::string& override_path) {
  std::error_code ec;
  if (!override_path.empty()) {
    const fs::path p(override_path);
    if (!fs::exists(p, ec)) ThrowInputError(p, 0, "the footage of {} does not exist", name);
    return p;
  }
  if (!fs::is_directory(shot, ec)) {
    ThrowInputError(shot, 0, "the shot folder does not exist or is not a folder");
  }
  std::vector<fs::path> found;
  if (fs::is_directory(shot / name, ec)) {
    found.push_back(shot / name);
  } else if (fs::exists(fs::symlink_status(shot / name, ec))) {
    // There, but not a folder to read (a link to itself or to nothing).
    const std::string why = DescribeUnreadable(shot / name);
    if (!why.empty()) ThrowInputError(shot / name, 0, "the footage of {} {}", name, why);
  }
  for (fs::directory_iterator it(shot, ec), end; !ec && it != end; it.increment(ec)) {
    if (it->path().stem() == name && IsVideoFile(it->path()) &&
        it->path().filename().string().front() != '.') {
      found.push_back(it->path());
    }
  }
  if (found.empty()) {
    ThrowInputError(shot, 0,
                    "no footage for camera {}: expected a video {}.mkv/.mov/.mp4/.avi or a "
                    "folder {}/ of numbered images (or set the footage option {} to its path)",
                    name, name, name, name);
  }
  if (found.size() > 1) {
    std::string list;
    for (const fs::path& p : found) list += " " + p.filename().string();
    ThrowInputError(shot, 0,
                    "camera {} has more than one source:{} (set the footage option {} to choose)",
                    name, list, name);
  }
  return found[0];
}

std::unique_ptr<CameraSource> OpenSource(const fs::path& path) {
  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);
  if (ec) ThrowInputError(path, 0, "cannot read: {}", ec.message());
  if (fs::is_directory(status)) return std::make_unique<ImageFolderSource>(path);
  if (!fs::is_regular_file(status)) {
    ThrowInputError(path, 0, "not a video file or an image folder");
  }
  if (!IsVideoFile(path)) {
    ThrowInputError(path, 0, "not a video (.mkv .mov .mp4 .avi .mxf .webm) or an image folder");
  }
  return std::make_unique<VideoSource>(path);
}

}  // namespace hmc
