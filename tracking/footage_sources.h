// The cameras' footage sources behind FootageReader (tracking/footage_reader.h):
// finding each camera's video or image folder in a shot, and decoding its
// frames in increasing frame number (docs/formats.md, "Footage input").
// Internal to tracking/.
#pragma once

#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace hmc {

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
  // Lists the numbered images of `dir`; throws InputError if there are none.
  explicit ImageFolderSource(const std::filesystem::path& dir);
  long long first_number() const { return numbered_.begin()->first; }
  // Numbers the frames (file number - base + first_frame) and decides the sequence's
  // image size from the headers of its first files: the size most of the
  // first three share (the expected one when one of them has it), so one
  // odd first file is a bad frame, not the size of the sequence.
  void SetBase(long long base, long long first_frame, const cv::Size& expected);
  cv::Size size() const override { return size_; }
  // The first file's header speaks for the sequence.
  std::string StatedTransfer(std::string* why) const override;
  int first() const override { return files_.begin()->first; }
  int last() const override { return files_.rbegin()->first; }
  cv::Mat Read(int frame, std::string* error) override;

 private:
  static cv::Mat Decode(const std::filesystem::path& path, std::string* error);

  std::filesystem::path dir_;
  std::map<long long, std::filesystem::path> numbered_;  // file number -> file
  std::map<int, std::filesystem::path> files_;           // frame -> file
  cv::Size size_;
};

// The source of camera `name`: the explicit path, else SHOT/<name>.<video
// ext> or SHOT/<name>/. Throws InputError naming what is missing or ambiguous.
std::filesystem::path FindSource(const std::filesystem::path& shot, const std::string& name,
                                 const std::string& override_path);

// An image folder's or a video's source (by what `path` is).
std::unique_ptr<CameraSource> OpenSource(const std::filesystem::path& path);

}  // namespace hmc
