// A video's SMPTE timecode (docs/formats.md, "Footage", frame numbers): the
// timecode a container carries for its first frame (a QuickTime/MP4 tmcd
// track, an MXF or Matroska TIMECODE tag), read through FFmpeg's
// libavformat, since OpenCV 4.6 exposes none; and timecode arithmetic
// (libavutil's, drop-frame included), so a mesh cache that starts later
// than the footage carries the timecode of its own first frame.
#pragma once

#include <filesystem>
#include <string>

namespace hmc {

// The timecode of the video's first frame ("HH:MM:SS:FF", ';' before the
// frames for drop-frame), as the container states it: the format's tags
// first, then each stream's. "" when the container carries none, or when
// `path` is not a video FFmpeg opens (the footage reader reports that).
std::string ReadVideoTimecode(const std::filesystem::path& path);

// `timecode` advanced by `frames` frames at `fps` frames/s: the timecode of
// frame 1 + frames when `timecode` is frame 1's. Drop-frame (';') is kept
// and counted as SMPTE 12M drops frame numbers (29.97 and 59.94 fps).
// Throws InputError naming `origin` when the timecode is malformed or does
// not fit the rate (a frame field of 30 at 30 fps).
std::string AdvanceTimecode(const std::string& timecode, double fps, int frames,
                            const std::string& origin);

}  // namespace hmc
