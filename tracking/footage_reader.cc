#include "tracking/footage_reader.h"

#include <algorithm>
#include <chrono>
#include <climits>
#include <cmath>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <optional>
#include <system_error>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>
#include <spdlog/spdlog.h>

#include "core/error.h"
#include "core/file_util.h"
#include "core/image_io.h"
#include "core/yaml_values.h"
#include "core/parallel.h"
#include "core/text.h"

namespace hmc {

namespace fs = std::filesystem;

void FootageOptions::Register(OptionFields* fields) {
  fields->Add("cam0", &cam0, "cam0 video or image folder (\"\" = SHOT/cam0.<ext> or SHOT/cam0/)");
  fields->Add("cam1", &cam1, "cam1 video or image folder (\"\" = SHOT/cam1.<ext> or SHOT/cam1/)");
  fields->Add("frames", &frames, "frame range A:B, inclusive; A: or :B open (\"\" = all)");
  fields->Add("offset1", &offset1, "cam1 frame = cam0 frame + offset1 (frames)");
}

void FootageOptions::RegisterTransfer(OptionFields* fields) {
  fields->SetGroup("footage");
  fields->Add("transfer", &transfer,
              "encoding of the footage's values: srgb | linear | auto (as each camera's files "
              "say: PNG sRGB/iCCP/gAMA, JPEG sRGB, an .mp4/.mov's colr box; linear where not "
              "stated)");
  fields->SetGroup("");
}

bool FootageOptions::Check() const {
  bool ok = true;
  if (transfer != "srgb" && transfer != "linear" && transfer != "auto") {
    spdlog::error("footage options: transfer must be srgb, linear or auto, got '{}'", transfer);
    ok = false;
  }
  try {
    ParseFrameRange(frames, "frames");
  } catch (const InputError& e) {
    spdlog::error("footage options: {}", e.what());
    ok = false;
  }
  if (offset1 < -100000 || offset1 > 100000) {
    spdlog::error("footage options: offset1 must be in [-100000, 100000], got {}", offset1);
    ok = false;
  }
  return ok;
}

FrameRange ParseFrameRange(const std::string& text, const std::string& origin) {
  FrameRange range{INT_MIN, INT_MAX};
  const std::string_view t = Trim(text);
  if (t.empty()) return range;
  const size_t colon = t.find(':');
  if (colon == std::string_view::npos || t.find(':', colon + 1) != std::string_view::npos) {
    throw InputError(fmt::format("{}: '{}' is not a frame range A:B", origin, text));
  }
  const std::string_view a = Trim(t.substr(0, colon));
  const std::string_view b = Trim(t.substr(colon + 1));
  if ((!a.empty() && !ParseInt(a, &range.first)) ||
      (!b.empty() && !ParseInt(b, &range.last)) || range.first > range.last) {
    throw InputError(fmt::format(
        "{}: '{}' is not a frame range A:B (integers, A <= B)", origin, text));
  }
  return range;
}

bool FootageFrame::complete() const {
  return std::all_of(images.begin(), images.end(),
                     [](const cv::Mat& m) { return !m.empty(); });
}

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

// One camera's source: decoded frames in increasing frame number.
class CameraSource {
 public:
  virtual ~CameraSource() = default;
  virtual cv::Size size() const = 0;
  virtual int first() const = 0;
  virtual int last() const = 0;
  // The image of `frame` (frames are asked for in increasing order), or
  // empty with `error` set.
  virtual cv::Mat Read(int frame, std::string* error) = 0;
  // Passes over the frames before `frame` (asked for in the same order as
  // Read) without producing their images: the next Read may ask for
  // `frame`. A video decodes them, or seeks where that is cheaper.
  virtual void SkipTo(int frame) { (void)frame; }
  // True once it is known that no frame >= `frame` will come (a video that
  // ended early: truncated, or without a declared length).
  virtual bool EndedBefore(int frame) const { return frame > last(); }
  virtual std::vector<std::string> warnings() const { return {}; }
  // Frames per second as the source declares it (0: unknown, an image folder).
  virtual double fps() const { return 0; }
  // What the source says of its values' encoding: "srgb", "linear" or ""
  // (not stated), and where it says so.
  virtual std::string StatedTransfer(std::string* why) const {
    *why = "not stated";
    return "";
  }
};

// A folder of numbered images. Frames are named by file number: the
// reader numbers every folder of the shot from the smallest first number
// among them (SetBase), so a missing first file is a missing frame of that
// camera, not a shift of all its frames, and a plate's own numbers are its
// frames' (docs/formats.md, "Footage input").
class ImageFolderSource : public CameraSource {
 public:
  explicit ImageFolderSource(const fs::path& dir) : dir_(dir) {
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
  long long first_number() const { return numbered_.begin()->first; }
  // Numbers the frames (file number - base + first_frame) and decides the sequence's
  // image size from the headers of its first files: the size most of the
  // first three share (the expected one when one of them has it), so one
  // odd first file is a bad frame, not the size of the sequence.
  void SetBase(long long base, long long first_frame, const cv::Size& expected) {
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
  cv::Size size() const override { return size_; }
  // The first file's header speaks for the sequence.
  std::string StatedTransfer(std::string* why) const override {
    const fs::path& file = numbered_.begin()->second;
    const ImageHeader h = ReadImageHeader(file);
    *why = h.transfer.empty() ? fmt::format("not stated in {}", file.filename().string())
                              : fmt::format("{} in {}", h.transfer_why, file.filename().string());
    return h.transfer;
  }
  int first() const override { return files_.begin()->first; }
  int last() const override { return files_.rbegin()->first; }
  cv::Mat Read(int frame, std::string* error) override {
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

 private:
  static cv::Mat Decode(const fs::path& path, std::string* error) {
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

  fs::path dir_;
  std::map<long long, fs::path> numbered_;  // file number -> file
  std::map<int, fs::path> files_;           // frame -> file
  cv::Size size_;
};

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

// The source of camera `name`: the explicit path, else SHOT/<name>.<video
// ext> or SHOT/<name>/.
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

}  // namespace

struct FootageReader::Impl {
  std::vector<std::string> names;
  std::vector<fs::path> paths;
  std::vector<std::unique_ptr<CameraSource>> sources;
  std::vector<int> offsets;  // camera frame = cam0 frame + offset
  std::vector<std::string> transfers, transfer_whys;  // per camera
  std::vector<std::string> warnings;
  int first = 1;
  int last = 0;
  int next = 1;
  bool source_warnings_added = false;
};

FootageReader::FootageReader(const fs::path& shot, const std::vector<std::string>& camera_names,
                             const FootageOptions& options,
                             const std::vector<cv::Size>& expected_sizes)
    : impl_(std::make_unique<Impl>()) {
  if (camera_names.empty()) throw InputError("footage: no cameras to read");
  const FrameRange range = ParseFrameRange(options.frames, "--frames");
  impl_->names = camera_names;
  for (size_t c = 0; c < camera_names.size(); ++c) {
    const std::string& name = camera_names[c];
    const std::string override_path =
        c == 0 ? options.cam0 : c == 1 ? options.cam1 : std::string();
    impl_->paths.push_back(FindSource(shot, name, override_path));
    impl_->sources.push_back(OpenSource(impl_->paths.back()));
    impl_->offsets.push_back(c == 1 ? options.offset1 : 0);
  }
  // The values' encoding per camera (docs/formats.md, "Footage input").
  for (size_t c = 0; c < impl_->sources.size(); ++c) {
    std::string why;
    std::string transfer = options.transfer;
    if (transfer == "auto") {
      transfer = impl_->sources[c]->StatedTransfer(&why);
      if (transfer.empty()) {
        transfer = "linear";
        why += "; assumed linear: set footage.transfer srgb for sRGB or BT.709 footage";
      }
    } else {
      why = "footage.transfer " + transfer;
    }
    impl_->transfers.push_back(transfer);
    impl_->transfer_whys.push_back(why);
  }
  // Image folders are paired by file number: all numbered from the
  // smallest first number among them (0 or 1 alike), so a camera whose
  // first file is missing starts one frame later instead of every frame
  // of it being paired with the other camera's previous one.
  std::vector<std::pair<size_t, ImageFolderSource*>> folders;
  for (size_t c = 0; c < impl_->sources.size(); ++c) {
    if (auto* folder = dynamic_cast<ImageFolderSource*>(impl_->sources[c].get())) {
      folders.emplace_back(c, folder);
    }
  }
  long long base = LLONG_MAX;
  for (const auto& [c, folder] : folders) base = std::min(base, folder->first_number());
  // The shot's first frame: the plate's own first number when every camera
  // is an image folder, so a sequence 1001-1012 is frames 1001-1012 in
  // every file hmc writes (issue 44, item 4); 1 for a sequence numbered
  // from 0 (hmc's frames start at 1) and beside a video (whose frames are
  // 1, 2, ...).
  const long long first_frame =
      folders.size() == impl_->sources.size() ? std::max(base, 1LL) : 1;
  for (const auto& [c, folder] : folders) {
    folder->SetBase(base, first_frame,
                    c < expected_sizes.size() ? expected_sizes[c] : cv::Size());
    if (folder->first_number() != base) {
      impl_->warnings.push_back(fmt::format(
          "{}'s first image file is number {}, the shot's first is {}: frames are paired by "
          "file number, so {} starts at frame {} (if its files are numbered differently, "
          "pair them with offset1)",
          camera_names[c], folder->first_number(), base, camera_names[c],
          folder->first_number() - base + first_frame));
    } else if (folders.size() < impl_->sources.size() && base > 1) {
      impl_->warnings.push_back(fmt::format(
          "{}'s first image file is number {}: it is frame 1, paired with the video's first "
          "frame (if files before it are missing, pair them with offset1)",
          camera_names[c], base));
    }
  }
  for (size_t c = 0; c < impl_->sources.size(); ++c) {
    const cv::Size size = impl_->sources[c]->size();
    if (c < expected_sizes.size() && expected_sizes[c] != size) {
      // FFmpeg turns a video by its rotation metadata (a phone, a camera
      // mounted on its side): width and height exchanged say so.
      const bool turned = size == cv::Size(expected_sizes[c].height, expected_sizes[c].width);
      ThrowInputError(impl_->paths[c], 0,
                      "image size {}x{} does not match the calibration's {}x{} for {}{}",
                      size.width, size.height, expected_sizes[c].width,
                      expected_sizes[c].height, camera_names[c],
                      turned ? " (turned by 90 degrees: rotation metadata in the video, or "
                               "frames exported rotated?)"
                             : "");
    }
  }
  // The common range, in cam0's numbering.
  int first = INT_MIN;
  int last = INT_MAX;
  for (size_t c = 0; c < impl_->sources.size(); ++c) {
    first = std::max(first, impl_->sources[c]->first() - impl_->offsets[c]);
    last = std::min(last, impl_->sources[c]->last() - impl_->offsets[c]);
  }
  for (size_t c = 0; c < impl_->sources.size(); ++c) {
    const int own_first = impl_->sources[c]->first() - impl_->offsets[c];
    const int own_last = impl_->sources[c]->last() - impl_->offsets[c];
    if (own_first != first || own_last != last) {
      impl_->warnings.push_back(fmt::format(
          "{} ({}) covers frames {}..{}, the cameras in common {}..{}: reading the common range",
          camera_names[c], impl_->paths[c].string(), own_first, own_last, first, last));
    }
  }
  // A range beyond the footage is read as far as there is footage, and
  // said (--frames 1:25 of a 20-frame shot, --frames 0:5).
  if ((range.first != INT_MIN && range.first < first) ||
      (range.last != INT_MAX && range.last > last)) {
    impl_->warnings.push_back(fmt::format(
        "--frames {} reaches beyond the footage's frames {}..{}: reading {}..{}", options.frames,
        first, last, std::max(first, range.first), std::min(last, range.last)));
  }
  first = std::max(first, range.first);
  last = std::min(last, range.last);
  if (first > last) {
    ThrowInputError(shot, 0, "no frame in common between the cameras and --frames '{}'",
                    options.frames);
  }
  impl_->first = first;
  impl_->last = last;
  impl_->next = first;
  for (const std::string& w : impl_->warnings) spdlog::warn("footage: {}", w);
}

FootageReader::~FootageReader() = default;

int FootageReader::num_cameras() const { return static_cast<int>(impl_->names.size()); }
const std::string& FootageReader::camera_name(int camera) const { return impl_->names[camera]; }
const fs::path& FootageReader::source(int camera) const { return impl_->paths[camera]; }
cv::Size FootageReader::image_size(int camera) const { return impl_->sources[camera]->size(); }
int FootageReader::first_frame() const { return impl_->first; }
int FootageReader::last_frame() const { return impl_->last; }
const std::vector<std::string>& FootageReader::warnings() const { return impl_->warnings; }
double FootageReader::fps() const { return impl_->sources[0]->fps(); }
const std::string& FootageReader::transfer(int camera) const { return impl_->transfers[camera]; }
const std::string& FootageReader::transfer_why(int camera) const {
  return impl_->transfer_whys[camera];
}

void FootageReader::Linearize(FootageFrame* frame) const {
  for (size_t c = 0; c < frame->images.size() && c < impl_->transfers.size(); ++c) {
    if (impl_->transfers[c] == "srgb" && !frame->images[c].empty()) {
      frame->images[c] = SrgbToLinear16(frame->images[c]);
    }
  }
}

bool FootageReader::Next(FootageFrame* frame) { return Next(frame, nullptr); }

// A source that no longer exists mid-shot (a network share that went away,
// a drive unplugged) is not a run of bad frames nor a truncated video: the
// read stops with an error naming it (docs/reliability.md).
void FootageReader::ThrowIfGone(const Impl& d) {
  for (size_t c = 0; c < d.paths.size(); ++c) {
    std::error_code ec;
    if (!fs::exists(d.paths[c], ec)) {
      ThrowInputError(d.paths[c], 0, "the footage of {} disappeared during the read (a network "
                      "share or drive gone?)", d.names[c]);
    }
  }
}

bool FootageReader::Next(FootageFrame* frame, const std::function<bool(int)>& wanted) {
  Impl& d = *impl_;
  for (;;) {
    if (d.next > d.last) {
      if (!d.source_warnings_added) {
        d.source_warnings_added = true;
        for (const auto& source : d.sources) {
          for (const std::string& w : source->warnings()) {
            spdlog::warn("footage: {}", w);
            d.warnings.push_back(w);
          }
        }
      }
      return false;
    }
    const int f = d.next;
    bool ended = false;
    for (size_t c = 0; c < d.sources.size(); ++c) {
      ended = ended || d.sources[c]->EndedBefore(f + d.offsets[c]);
    }
    if (ended) {
      ThrowIfGone(d);
      d.last = f - 1;  // a video ended early: what decoded is the shot
      continue;
    }
    // The cameras' sources are independent: they decode side by side.
    const int64_t num_sources = static_cast<int64_t>(d.sources.size());
    if (wanted && !wanted(f)) {
      // On to the next wanted frame (or past the last), passing over the
      // frames between in one go so that a video may seek.
      int g = f + 1;
      while (g <= d.last && !wanted(g)) ++g;
      if (g <= d.last) {
        ParallelFor(0, num_sources, [&](int64_t c) { d.sources[c]->SkipTo(g + d.offsets[c]); });
      }
      d.next = g;
      continue;
    }
    ++d.next;
    frame->frame = f;
    frame->images.assign(d.sources.size(), cv::Mat());
    frame->errors.assign(d.sources.size(), std::string());
    ParallelFor(0, num_sources, [&](int64_t c) {
      frame->images[c] = d.sources[c]->Read(f + d.offsets[c], &frame->errors[c]);
    });
    for (size_t c = 0; c < d.sources.size(); ++c) {
      if (frame->images[c].empty()) {
        ThrowIfGone(d);
        const std::string error = frame->errors[c];
        frame->errors[c] = error.empty() ? "no image" : error;
        const std::string w = fmt::format("frame {} {}: {}", f, d.names[c], frame->errors[c]);
        spdlog::warn("footage: {}", w);
        d.warnings.push_back(w);
      }
    }
    return true;
  }
}

namespace {

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

FootageReadAhead::FootageReadAhead(FootageReader* reader, bool linearize)
    : reader_(reader), linearize_(linearize), next_(std::async(std::launch::async, [this] { return Read(); })) {}

FootageReadAhead::~FootageReadAhead() {
  if (next_.valid()) next_.wait();
}

std::unique_ptr<FootageFrame> FootageReadAhead::Read() {
  auto frame = std::make_unique<FootageFrame>();
  if (!reader_->Next(frame.get())) return nullptr;
  if (linearize_) reader_->Linearize(frame.get());
  return frame;
}

std::unique_ptr<FootageFrame> FootageReadAhead::Next() {
  if (!next_.valid()) return nullptr;
  std::unique_ptr<FootageFrame> frame = next_.get();
  if (frame) next_ = std::async(std::launch::async, [this] { return Read(); });
  return frame;
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
