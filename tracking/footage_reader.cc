// The footage reader: each camera's source (tracking/footage_sources.h) paired frame by
// frame, in cam0's numbering; the values' encoding is in tracking/footage_transfer.cc.
#include "tracking/footage_reader.h"

#include <algorithm>
#include <climits>
#include <functional>
#include <system_error>

#include <spdlog/spdlog.h>

#include "core/error.h"
#include "core/parallel.h"
#include "core/text.h"
#include "tracking/footage_sources.h"

namespace hmc {

namespace fs = std::filesystem;

void FootageOptions::Register(OptionFields* fields) {
  fields->Add("cam0", &cam0, "cam0 video or image folder (\"\" = SHOT/cam0.<ext> or SHOT/cam0/)");
  fields->Add("cam1", &cam1, "cam1 video or image folder (\"\" = SHOT/cam1.<ext> or SHOT/cam1/)");
  fields->Add("frames", &frames, "frame range A:B, inclusive; A: or :B open (\"\" = all)");
  fields->Add("offset1", &offset1, "cam1 frame = cam0 frame + offset1 (frames)")
      .In(-100000, 100000);
}

void FootageOptions::RegisterTransfer(OptionFields* fields) {
  fields->SetGroup("footage");
  fields->Add("transfer", &transfer,
              "encoding of the footage's values: srgb | linear | auto (as each camera's files "
              "say: PNG sRGB/iCCP/gAMA, JPEG sRGB, an .mp4/.mov's colr box; linear where not "
              "stated)")
      .OneOf({"srgb", "linear", "auto"});
  fields->SetGroup("");
}

bool FootageOptions::Check() const {
  CHECK_OPTION_LIMITS();
  // transfer is declared by RegisterTransfer, which CHECK_OPTION_LIMITS does not see.
  CHECK_OPTION(transfer == "srgb" || transfer == "linear" || transfer == "auto");
  try {
    ParseFrameRange(frames, "frames");
  } catch (const InputError& e) {
    spdlog::error("footage options: {}", e.what());
    return false;
  }
  return true;
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

}  // namespace hmc
