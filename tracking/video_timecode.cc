#include "tracking/video_timecode.h"

extern "C" {
#include <libavformat/avformat.h>
#include <libavutil/dict.h>
#include <libavutil/mathematics.h>
#include <libavutil/timecode.h>
}

#include <cmath>
#include <cstdio>
#include <memory>

#include "core/error.h"

namespace hmc {
namespace {

std::string Tag(const AVDictionary* tags) {
  // av_dict_get matches keys without regard to case: "timecode" (QuickTime,
  // MXF) and "TIMECODE" (Matroska).
  const AVDictionaryEntry* entry = av_dict_get(tags, "timecode", nullptr, 0);
  return entry && entry->value ? entry->value : "";
}

}  // namespace

std::string ReadVideoTimecode(const std::filesystem::path& path) {
  AVFormatContext* raw = nullptr;
  if (avformat_open_input(&raw, path.c_str(), nullptr, nullptr) < 0) return "";
  const std::unique_ptr<AVFormatContext, void (*)(AVFormatContext*)> context(
      raw, [](AVFormatContext* c) { avformat_close_input(&c); });
  if (std::string tc = Tag(context->metadata); !tc.empty()) return tc;
  for (unsigned s = 0; s < context->nb_streams; ++s) {
    if (std::string tc = Tag(context->streams[s]->metadata); !tc.empty()) return tc;
  }
  return "";
}

std::string AdvanceTimecode(const std::string& timecode, double fps, int frames,
                            const std::string& origin) {
  if (!(fps > 0) || !std::isfinite(fps)) {
    ThrowInputError(origin, 0, "timecode '{}': the frame rate {} is not positive", timecode, fps);
  }
  // 29.97 -> 30000/1001: the rate libavutil knows drop-frame for.
  const AVRational rate = av_d2q(fps, 1001000);
  AVTimecode tc;
  int hh = 0, mm = 0, ss = 0, ff = 0;
  char separator = 0;
  const bool parts = std::sscanf(timecode.c_str(), "%d:%d:%d%c%d", &hh, &mm, &ss, &separator,
                                 &ff) == 5 &&
                     mm < 60 && ss < 60 && ff < std::lround(fps);
  if (!parts || av_timecode_init_from_string(&tc, rate, timecode.c_str(), nullptr) < 0) {
    ThrowInputError(origin, 0,
                    "timecode '{}' is not HH:MM:SS:FF (or HH:MM:SS;FF, drop-frame) at {} "
                    "frames/s",
                    timecode, fps);
  }
  tc.flags |= AV_TIMECODE_FLAG_24HOURSMAX;  // SMPTE timecode wraps at midnight
  char text[AV_TIMECODE_STR_SIZE];
  return av_timecode_make_string(&tc, text, frames);
}

}  // namespace hmc
