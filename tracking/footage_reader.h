// Reading a shot's footage, frame by frame, for every command that looks at
// pixels (hmc track, hmc undistort, hmc calibrate, hmc run). Format and
// rules: docs/formats.md, "Footage input".
//
// A shot folder holds, per camera (named as in calibration.yaml, "cam0",
// "cam1"), either a video `<name>.<ext>` (anything FFmpeg decodes through
// cv::VideoCapture with cv::CAP_FFMPEG: FFV1 .mkv, ProRes .mov, H.264 .mp4,
// .avi) or a folder `<name>/` of numbered images (PNG, TIFF, JPEG; 8 or 16
// bit, grey or colour). `FootageOptions::cam0` / `cam1` override the
// convention with an explicit path.
//
// Frame numbers: a video's n-th frame (by its timestamp) is frame n; an
// image sequence's frame is its file number (the plate's own: 1001-1012
// are frames 1001-1012), except that a shot numbered from 0 is read from
// 1 (frame = file number + 1) and an image folder beside a video is
// numbered from 1 like the video. The cameras' files pair by number (the
// shot's first number is the smallest among its image folders), so a
// missing file is a missing frame, even a camera's first (warned). Hidden files (macOS `._*`) are not
// frames. Each file's header is checked against the sequence's size before
// it is decoded. cam1's frame f + offset1 pairs with cam0's frame f; frames
// are reported in cam0's numbering.
//
// Frames stream: only the current frame is held, so memory does not grow
// with the length of the shot. A frame that fails to decode in one camera
// is delivered with that camera's image empty and the reason set (the other
// camera's image is still there); the frames after it are read normally.
#pragma once

#include <filesystem>
#include <functional>
#include <future>
#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "core/options.h"

namespace hmc {

struct FootageOptions {
  std::string cam0;     // cam0 video or image folder ("" = SHOT/cam0.<ext> or SHOT/cam0/)
  std::string cam1;     // cam1 video or image folder ("" = SHOT/cam1.<ext> or SHOT/cam1/)
  std::string frames;   // inclusive range "A:B" of frame numbers; "A:" or ":B" open ("" = all)
  int offset1 = 0;      // cam1 frame number = cam0 frame number + offset1 (frames)
  // The encoding of the footage's values: srgb | linear | auto (what each
  // camera's files say: PNG sRGB/iCCP/gAMA chunks, JPEG, an .mp4/.mov's
  // colr box; linear where nothing is said). Applied by FootageReader::
  // Linearize, which only the commands that measure light call.
  std::string transfer = "auto";

  // Adds the fields without a group ("cam0", "frames", "offset1", ...).
  void Register(OptionFields* fields);
  // Adds "footage.transfer": for the commands that linearise (hmc track).
  void RegisterTransfer(OptionFields* fields);
  bool Check() const;
};

// The parsed `frames` range; first/last are inclusive (INT_MIN/INT_MAX when
// open). Throws InputError naming `origin` on a malformed range.
struct FrameRange {
  int first;
  int last;
  bool Contains(int frame) const { return frame >= first && frame <= last; }
};
FrameRange ParseFrameRange(const std::string& text, const std::string& origin);

struct FootageFrame {
  int frame = 0;                     // frame number (cam0's numbering)
  std::vector<cv::Mat> images;       // per camera: grey, CV_8U or CV_16U as stored; empty if missing
  std::vector<std::string> errors;   // per camera: why the image is missing ("" if present)

  bool complete() const;             // every camera's image present
};

class FootageReader {
 public:
  // Opens every camera's source under `shot` (or the override in
  // `options`). Throws InputError naming the path when a source is missing,
  // unreadable, not a video or image folder, empty, or its image size
  // differs from `expected_sizes[c]` (when given; e.g. from the
  // calibration). Warns (warnings()) when the cameras' frame ranges differ:
  // the common range is read.
  FootageReader(const std::filesystem::path& shot,
                const std::vector<std::string>& camera_names,
                const FootageOptions& options,
                const std::vector<cv::Size>& expected_sizes = {});
  ~FootageReader();
  FootageReader(const FootageReader&) = delete;
  FootageReader& operator=(const FootageReader&) = delete;

  int num_cameras() const;
  const std::string& camera_name(int camera) const;
  const std::filesystem::path& source(int camera) const;
  cv::Size image_size(int camera) const;
  // The frames that will be read (cam0 numbering, after the range and the
  // offset); frames in between may still fail to decode.
  int first_frame() const;
  int last_frame() const;
  int num_frames() const { return last_frame() - first_frame() + 1; }
  // cam0's frame rate as its video declares it (frames per second); 0 when
  // unknown (an image folder).
  double fps() const;
  // The encoding of a camera's values, "srgb" or "linear" (options.transfer,
  // or with auto what the source says), and why ("footage.transfer",
  // "PNG sRGB chunk in frame_000001.png", "not stated: assumed linear").
  const std::string& transfer(int camera) const;
  const std::string& transfer_why(int camera) const;
  // Turns the images of the sRGB cameras into linear light, 16-bit (the
  // sRGB curve inverted; 16 bits keep the dark levels apart that 8 would
  // merge): what the dot detector measures (docs/tracking.md, "Images").
  // Linear cameras' images are left as they are.
  void Linearize(FootageFrame* frame) const;

  // Reads the next frame in order; false after the last one. Never throws
  // for a bad frame: the frame comes back with the camera's error set.
  // Throws InputError when a camera's source no longer exists (a share
  // gone mid-run): that is not a bad frame.
  bool Next(FootageFrame* frame);
  // Reads the next frame for which wanted(frame number) is true; the frames
  // before it are passed over without being converted into images. A
  // video decodes them (its frames may depend on earlier ones), or seeks
  // when the next wanted frame is far enough ahead that a seek measures
  // cheaper; a seek that lands wrong is undone by reading up to the frame,
  // so the images are those of reading every frame. For readers that need
  // a sample of the frames (hmc calibrate, the report's contact sheet).
  bool Next(FootageFrame* frame, const std::function<bool(int)>& wanted);

  // Shot-level warnings (different lengths, a truncated video, ...), and
  // per-frame decode failures ("frame 17 cam1: ...") as they happen.
  const std::vector<std::string>& warnings() const;

 private:
  struct Impl;
  static void ThrowIfGone(const Impl& d);
  std::unique_ptr<Impl> impl_;
};

// Reads a FootageReader's frames one ahead: the next frame is decoded (and
// with `linearize`, Linearize'd) on another thread while the caller works
// on the current one. Next() returns null after the last frame; what the
// reader throws is thrown by Next().
class FootageReadAhead {
 public:
  FootageReadAhead(FootageReader* reader, bool linearize);
  ~FootageReadAhead();  // waits for the frame being read
  std::unique_ptr<FootageFrame> Next();

 private:
  std::unique_ptr<FootageFrame> Read();
  FootageReader* reader_;
  bool linearize_;
  std::future<std::unique_ptr<FootageFrame>> next_;
};

// What an .mp4 or .mov video says of its values' encoding (its colr box's
// transfer characteristic, ITU-T H.273): "srgb" for BT.709, BT.601, sRGB
// and BT.2020 (the BT.709 curve), "linear", or "" (not said, another
// container, or a curve hmc does not invert); `why` says which.
std::string VideoTransfer(const std::filesystem::path& path, std::string* why);

// An sRGB-encoded grey image (8 or 16 bit) in linear light, 16-bit.
cv::Mat SrgbToLinear16(const cv::Mat& image);

// 8-bit view of a grey image from the reader (16-bit scaled by 1/257).
cv::Mat ToGrey8(const cv::Mat& image);
// Float view in [0, 1] (8-bit / 255, 16-bit / 65535).
cv::Mat ToGreyFloat(const cv::Mat& image);

}  // namespace hmc
