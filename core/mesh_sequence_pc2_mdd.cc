#include "core/mesh_sequence_codecs.h"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <exception>
#include <fstream>
#include <iterator>
#include <limits>
#include <ostream>
#include <string_view>
#include <utility>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "core/error.h"
#include "core/file_util.h"
#include "core/obj_io.h"
#include "core/parallel.h"

namespace hmc::sequence_io {

namespace {

// The size in bytes that a point cache's header promises: `header_bytes`
// then `count` entries (samples or frames, named by `unit`) of `entry_bytes`
// each. Bounded by division first: a lying header's product would overflow
// (found by fuzzing, docs/reliability.md).
int64_t PromisedBytes(const BinaryFile& file, const char* unit, int32_t count,
                      int32_t num_points, int64_t header_bytes,
                      int64_t entry_bytes) {
  if (int64_t{count} > (std::numeric_limits<int64_t>::max() / 2) / entry_bytes) {
    ThrowInputError(file.path(), 0,
                    "header promises {} {} x {} points, more than the file's {} bytes",
                    count, unit, num_points, file.size());
  }
  return header_bytes + int64_t{count} * entry_bytes;
}

// The file's size is not the `expected` one its header promises.
[[noreturn]] void ThrowSizeMismatch(const BinaryFile& file, const char* unit,
                                    int32_t count, int32_t num_points,
                                    int64_t expected) {
  ThrowInputError(file.path(), 0,
                  "{}: header promises {} {} x {} points ({} bytes), "
                  "the file has {} bytes",
                  file.size() < expected ? "truncated" : "trailing data",
                  count, unit, num_points, expected, file.size());
}

}  // namespace

// ---------------------------------------------------------------------------
// .pc2: Blender / 3ds Max point cache. Layout as Blender's Mesh Cache
// modifier reads it (MOD_meshcache_pc2.cc): little-endian header
// {char[12] "POINTCACHE2\0", int32 version (1), int32 points, float32 start
// frame, float32 sample rate, int32 samples}, then samples x points x 3
// float32.

void WritePc2Header(std::ostream& out, int num_points, int start_frame,
                    int64_t num_frames) {
  char header[kPc2HeaderBytes];
  std::memcpy(header, kPc2Magic, 12);
  PutU32(header + 12, 1, false);
  PutU32(header + 16, static_cast<uint32_t>(num_points), false);
  PutF32(header + 20, static_cast<float>(start_frame), false);
  PutF32(header + 24, 1.0f, false);
  PutU32(header + 28, static_cast<uint32_t>(num_frames), false);
  out.write(header, kPc2HeaderBytes);
}

void WritePc2(const fs::path& path, const MeshSequence& seq) {
  const int num_points = CheckFrames(path, seq);
  WriteFileAtomic(
      path,
      [&](std::ostream& out) {
        WritePc2Header(out, num_points, seq.start_frame,
                       static_cast<int64_t>(seq.frames.size()));
        WriteFramesF32(out, seq, /*big_endian=*/false);
      },
      /*binary=*/true);
}

MeshSequence ReadPc2(const fs::path& path,
                     const MeshSequenceReadOptions& options) {
  BinaryFile file(path);
  if (file.size() < kPc2HeaderBytes) {
    ThrowInputError(path, 0,
                    "truncated: {} bytes, shorter than the {}-byte PC2 header",
                    file.size(), kPc2HeaderBytes);
  }
  char header[kPc2HeaderBytes];
  file.Read(header, kPc2HeaderBytes);
  if (std::memcmp(header, kPc2Magic, 12) != 0) {
    ThrowInputError(path, 0,
                    "not a PC2 point cache (does not start with "
                    "\"POINTCACHE2\\0\")");
  }
  const int32_t version = GetI32(header + 12, false);
  const int32_t num_points = GetI32(header + 16, false);
  const float start = GetF32(header + 20, false);
  const float sample_rate = GetF32(header + 24, false);
  const int32_t num_samples = GetI32(header + 28, false);
  if (version != 1) {
    ThrowInputError(path, 0, "unsupported PC2 version {} (expected 1)",
                    version);
  }
  if (num_points <= 0) {
    ThrowInputError(path, 0, "header gives {} points (must be positive)",
                    num_points);
  }
  if (num_samples <= 0) {
    ThrowInputError(path, 0, "header gives {} samples (must be positive)",
                    num_samples);
  }
  // A sample rate other than one sample per frame would make the samples
  // sub- or super-frames, which a MeshSequence (one entry per frame) cannot
  // say.
  if (sample_rate != 1.0f) {
    ThrowInputError(path, 0,
                    "sample rate {} is not supported (only 1: one sample per "
                    "frame)",
                    sample_rate);
  }
  if (!std::isfinite(start) || start != std::round(start) ||
      std::abs(start) > kMaxFrameNumber) {
    ThrowInputError(path, 0, "start frame {} is not a whole frame number",
                    start);
  }
  const int64_t expected =
      PromisedBytes(file, "samples", num_samples, num_points, kPc2HeaderBytes,
                    int64_t{num_points} * 12);
  if (file.size() != expected) {
    ThrowSizeMismatch(file, "samples", num_samples, num_points, expected);
  }
  CheckTopologyCount(path, options.topology, num_points);

  MeshSequence seq;
  seq.start_frame = options.start_frame.value_or(static_cast<int>(start));
  seq.fps = options.fps > 0 ? options.fps : kDefaultFps;
  seq.frames.reserve(num_samples);
  for (int s = 0; s < num_samples; ++s) {
    if (options.wanted && !options.wanted(seq.start_frame + s)) {
      file.Skip(int64_t{num_points} * 12);
      seq.frames.emplace_back();
      continue;
    }
    seq.frames.push_back(file.ReadFrame(num_points, /*big_endian=*/false, s));
  }
  if (options.topology != nullptr) seq.topology = *options.topology;
  return seq;
}

// ---------------------------------------------------------------------------
// .mdd: big-endian {int32 frames, int32 points, frames x float32 time (s)},
// then frames x points x 3 float32 (Blender's MOD_meshcache_mdd.cc). We
// write time = frame number / fps, so a Mesh Cache modifier in "Seconds"
// time mode lines the frames up with the scene's.

void WriteMddHeader(std::ostream& out, int num_points, int start_frame,
                    int64_t num_frames, double fps) {
  std::string header(8 + 4 * static_cast<size_t>(num_frames), '\0');
  PutU32(header.data(), static_cast<uint32_t>(num_frames), true);
  PutU32(header.data() + 4, static_cast<uint32_t>(num_points), true);
  for (int64_t f = 0; f < num_frames; ++f) {
    const double time_s = (start_frame + static_cast<double>(f)) / fps;
    PutF32(header.data() + 8 + 4 * f, static_cast<float>(time_s), true);
  }
  out.write(header.data(), static_cast<std::streamsize>(header.size()));
}

void WriteMdd(const fs::path& path, const MeshSequence& seq) {
  const int num_points = CheckFrames(path, seq);
  WriteFileAtomic(
      path,
      [&](std::ostream& out) {
        WriteMddHeader(out, num_points, seq.start_frame,
                       static_cast<int64_t>(seq.frames.size()), seq.fps);
        WriteFramesF32(out, seq, /*big_endian=*/true);
      },
      /*binary=*/true);
}

// How far (in frames) time t may sit from its frame at `fps`: one float32
// ulp of t (2 x 2^-24 |t|: the writer's rounding and ours) plus a
// thousandth of a frame.
double FrameTolerance(double time_s, double fps) {
  return 1e-3 + 2 * std::ldexp(std::abs(time_s), -24) * fps;
}

// Whether times[i] * fps lies on the whole frame start + i for every i, and
// which `start`; with `relative`, only the spacing is checked.
bool OnConsecutiveFrames(const std::vector<float>& times, double fps,
                         bool relative, int* start) {
  const double first = static_cast<double>(times[0]) * fps;
  const double rounded = relative ? first : std::round(first);
  if (std::abs(rounded) > kMaxFrameNumber) return false;
  for (size_t i = 0; i < times.size(); ++i) {
    const double frame = static_cast<double>(times[i]) * fps;
    if (std::abs(frame - rounded - static_cast<double>(i)) >
        FrameTolerance(times[i], fps)) {
      return false;
    }
  }
  *start = static_cast<int>(std::round(first));
  return true;
}

// The frame rate of evenly spaced float32 frame times (two or more), 0 if
// none fits. The spacing alone is only as precise as float32 times are (at
// frame 200000 of 60 fps, 0.24 ms in 3333 s: 1.5% of a two-frame span), so
// the whole rates within that precision are tried first, nearest first,
// then NTSC rates (N x 1000/1001), then the estimate itself; the first rate
// that puts every time on consecutive whole frames wins. Whole rates go
// first because the times of NTSC rate N x 1000/1001 from frame 1001 k are
// those of rate N from frame 1000 k: there the file cannot tell them apart.
double FpsFromTimes(const std::vector<float>& times, bool relative) {
  const double t0 = times.front();
  const double t1 = times.back();
  const double span = t1 - t0;
  const double estimate = static_cast<double>(times.size() - 1) / span;
  const double uncertainty =
      estimate * std::ldexp(std::abs(t0) + std::abs(t1), -24) / span +
      1e-9 * estimate;
  std::vector<double> candidates;
  for (const bool ntsc : {false, true}) {
    // Whole rates n, or NTSC rates n * 1000 / 1001 (computed so, as the
    // usual constants 24000.0 / 1001 and 30000.0 / 1001 are).
    const double scale = ntsc ? 1.001 : 1.0;
    std::vector<double> rates;
    const double low =
        std::max(1.0, std::ceil((estimate - uncertainty) * scale));
    const double high = std::floor((estimate + uncertainty) * scale);
    for (double n = low; n <= high && rates.size() < 1000; ++n) {
      rates.push_back(ntsc ? n * 1000.0 / 1001.0 : n);
    }
    std::sort(rates.begin(), rates.end(), [&](double a, double b) {
      return std::abs(a - estimate) < std::abs(b - estimate);
    });
    candidates.insert(candidates.end(), rates.begin(), rates.end());
  }
  candidates.push_back(estimate);
  int start = 0;
  for (const double candidate : candidates) {
    if (OnConsecutiveFrames(times, candidate, relative, &start)) {
      return candidate;
    }
  }
  return 0.0;
}

MeshSequence ReadMdd(const fs::path& path,
                     const MeshSequenceReadOptions& options) {
  BinaryFile file(path);
  if (file.size() < 8) {
    ThrowInputError(path, 0,
                    "truncated: {} bytes, shorter than the 8-byte MDD header",
                    file.size());
  }
  char header[8];
  file.Read(header, 8);
  const int32_t num_frames = GetI32(header, true);
  const int32_t num_points = GetI32(header + 4, true);
  if (num_frames <= 0 || num_points <= 0) {
    ThrowInputError(path, 0,
                    "header gives {} frames of {} points (both must be "
                    "positive; is this an MDD file?)",
                    num_frames, num_points);
  }
  const int64_t frame_bytes = int64_t{num_points} * 12;
  // Each frame: its float32 time, then its points.
  const int64_t expected = PromisedBytes(file, "frames", num_frames,
                                         num_points, 8, frame_bytes + 4);
  // Blender's own MDD exporter writes one extra "rest" frame before the
  // frames its header counts; accept it and drop it.
  const bool has_rest_frame = file.size() == expected + frame_bytes;
  if (file.size() != expected && !has_rest_frame) {
    ThrowSizeMismatch(file, "frames", num_frames, num_points, expected);
  }
  CheckTopologyCount(path, options.topology, num_points);

  std::string time_bytes(static_cast<size_t>(num_frames) * 4, '\0');
  file.Read(time_bytes.data(), static_cast<int64_t>(time_bytes.size()));
  std::vector<float> times(num_frames);
  for (int f = 0; f < num_frames; ++f) {
    times[f] = GetF32(time_bytes.data() + 4 * f, true);
    if (!std::isfinite(times[f]) || (f > 0 && !(times[f] > times[f - 1]))) {
      ThrowInputError(path, 0,
                      "frame times must be finite and increasing; time {} is "
                      "{}",
                      f, times[f]);
    }
  }

  // Frame numbers from times: each time must sit on a whole frame, and the
  // frames must be consecutive, since a MeshSequence has no gaps.
  MeshSequence seq;
  const bool relative = options.start_frame.has_value();
  seq.fps = options.fps > 0    ? options.fps
            : num_frames >= 2 ? FpsFromTimes(times, relative)
                               : kDefaultFps;
  int start = 0;
  if (seq.fps == 0 ||
      !OnConsecutiveFrames(times, seq.fps, relative, &start)) {
    ThrowInputError(path, 0,
                    "frame times {} .. {} s do not fall on consecutive whole "
                    "frames at {}; give the frame rate (and start frame) "
                    "explicitly",
                    times.front(), times.back(),
                    seq.fps > 0 ? fmt::format("{} fps", seq.fps)
                                : std::string("any frame rate"));
  }
  seq.start_frame = options.start_frame.value_or(start);
  if (has_rest_frame) {
    spdlog::warn("{}: one frame more than the header counts (Blender's MDD "
                 "rest frame): skipped",
                 path.string());
    file.ReadFrame(num_points, /*big_endian=*/true, -1);
  }
  seq.frames.reserve(num_frames);
  for (int f = 0; f < num_frames; ++f) {
    seq.frames.push_back(file.ReadFrame(num_points, /*big_endian=*/true, f));
  }
  if (options.topology != nullptr) seq.topology = *options.topology;
  return seq;
}


}  // namespace hmc::sequence_io
