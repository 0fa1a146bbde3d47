#include "core/mesh_sequence.h"

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

namespace hmc {
namespace {

namespace fs = std::filesystem;

constexpr double kDefaultFps = 30.0;
constexpr char kPc2Magic[12] = {'P', 'O', 'I', 'N', 'T', 'C', 'A',
                                'C', 'H', 'E', '2', '\0'};
constexpr int64_t kPc2HeaderBytes = 32;  // magic, version, points, start,
                                         // sample rate, samples
// Frame numbers and the PC2 start frame travel as float32, exact up to 2^24.
constexpr int kMaxFrameNumber = 1 << 24;

// ---------------------------------------------------------------------------
// Validation shared by the writers.

// Checks what every format needs: at least one frame, one vertex count, and
// values a float32 file can hold (all formats are float32 in the DCCs that
// read them). Returns the vertex count.
int CheckFrames(const fs::path& path, const MeshSequence& seq) {
  if (seq.frames.empty()) {
    ThrowInputError(path, 0, "cannot write a mesh sequence with no frames");
  }
  const int64_t num_points = seq.frames[0].rows();
  if (num_points == 0) {
    ThrowInputError(path, 0, "cannot write a mesh sequence with no vertices");
  }
  if (!(seq.fps > 0) || !std::isfinite(seq.fps)) {
    ThrowInputError(path, 0, "cannot write: frame rate {} is not positive",
                    seq.fps);
  }
  const int64_t last_frame =
      static_cast<int64_t>(seq.start_frame) + seq.frames.size() - 1;
  if (std::abs(static_cast<int64_t>(seq.start_frame)) > kMaxFrameNumber ||
      std::abs(last_frame) > kMaxFrameNumber) {
    ThrowInputError(path, 0,
                    "cannot write: frame numbers {}..{} exceed +-{} (float32 "
                    "frame numbers)",
                    seq.start_frame, last_frame, kMaxFrameNumber);
  }
  constexpr double kFloatMax = std::numeric_limits<float>::max();
  for (size_t f = 0; f < seq.frames.size(); ++f) {
    const MatX3d& X = seq.frames[f];
    if (X.rows() != num_points) {
      ThrowInputError(path, 0,
                      "cannot write: frame {} has {} vertices, frame {} has {}",
                      seq.start_frame + static_cast<int64_t>(f), X.rows(),
                      seq.start_frame, num_points);
    }
    for (int64_t v = 0; v < X.rows(); ++v) {
      for (int axis = 0; axis < 3; ++axis) {
        const double x = X(v, axis);
        if (!std::isfinite(x) || std::abs(x) > kFloatMax) {
          ThrowInputError(path, 0,
                          "cannot write: vertex {} of frame {} is {} (not a "
                          "finite float32)",
                          v, seq.start_frame + static_cast<int64_t>(f), x);
        }
      }
    }
  }
  return static_cast<int>(num_points);
}

// The topology to write with `num_points` vertices: seq.topology's triangles
// and UVs, positions of the first frame.
TriMesh TopologyForWrite(const fs::path& path, const MeshSequence& seq,
                         int num_points) {
  const TriMesh& topology = seq.topology;
  if (topology.NumFaces() == 0) {
    ThrowInputError(path, 0,
                    "this format stores triangles, but the sequence has none "
                    "(give the topology, e.g. hmc convert --topology)");
  }
  if (topology.NumVertices() != 0 && topology.NumVertices() != num_points) {
    ThrowInputError(path, 0, "topology has {} vertices, the frames have {}",
                    topology.NumVertices(), num_points);
  }
  if (topology.F.minCoeff() < 0 || topology.F.maxCoeff() >= num_points) {
    ThrowInputError(path, 0,
                    "topology has vertex indices outside 0..{} (the frames' "
                    "vertex count)",
                    num_points - 1);
  }
  if (topology.HasUVs() &&
      (topology.FUV.rows() != topology.F.rows() || topology.FUV.minCoeff() < 0 ||
       topology.FUV.maxCoeff() >= topology.UV.rows())) {
    ThrowInputError(path, 0, "topology has inconsistent UV indices");
  }
  TriMesh mesh;
  mesh.V = seq.frames[0];
  mesh.F = topology.F;
  mesh.UV = topology.UV;
  mesh.FUV = topology.FUV;
  return mesh;
}

// ---------------------------------------------------------------------------
// Binary helpers: explicit byte order, independent of the host's.

void PutU32(char* out, uint32_t value, bool big_endian) {
  for (int i = 0; i < 4; ++i) {
    const int shift = big_endian ? 8 * (3 - i) : 8 * i;
    out[i] = static_cast<char>((value >> shift) & 0xffu);
  }
}

uint32_t GetU32(const char* in, bool big_endian) {
  uint32_t value = 0;
  for (int i = 0; i < 4; ++i) {
    const int shift = big_endian ? 8 * (3 - i) : 8 * i;
    value |= static_cast<uint32_t>(static_cast<unsigned char>(in[i])) << shift;
  }
  return value;
}

void PutF32(char* out, float value, bool big_endian) {
  uint32_t bits;
  std::memcpy(&bits, &value, 4);
  PutU32(out, bits, big_endian);
}

float GetF32(const char* in, bool big_endian) {
  const uint32_t bits = GetU32(in, big_endian);
  float value;
  std::memcpy(&value, &bits, 4);
  return value;
}

int32_t GetI32(const char* in, bool big_endian) {
  return static_cast<int32_t>(GetU32(in, big_endian));
}

// Writes each frame as V x 3 float32.
void WriteFramesF32(std::ostream& out, const MeshSequence& seq,
                    bool big_endian) {
  std::string buffer;
  for (const MatX3d& X : seq.frames) {
    buffer.resize(static_cast<size_t>(X.rows()) * 12);
    char* p = buffer.data();
    for (int64_t v = 0; v < X.rows(); ++v) {
      for (int axis = 0; axis < 3; ++axis, p += 4) {
        PutF32(p, static_cast<float>(X(v, axis)), big_endian);
      }
    }
    out.write(buffer.data(), static_cast<std::streamsize>(buffer.size()));
  }
}

// A binary file read in full with its size checked against what the header
// promises before anything is allocated from header values.
class BinaryFile {
 public:
  explicit BinaryFile(const fs::path& path) : path_(path) {
    if (!fs::is_regular_file(path)) {
      ThrowInputError(path, 0, fs::exists(path) ? "not a regular file"
                                                : "file does not exist");
    }
    size_ = static_cast<int64_t>(fs::file_size(path));
    in_.open(path, std::ios::binary);
    if (!in_) ThrowInputError(path, 0, "cannot open for reading");
  }
  int64_t size() const { return size_; }

  void Read(char* out, int64_t bytes) {
    in_.read(out, bytes);
    if (in_.gcount() != bytes) {
      ThrowInputError(path_, 0, "read failed (file shrank while reading?)");
    }
  }

  // Reads num_points x 3 float32, checking each value is finite.
  MatX3d ReadFrame(int64_t num_points, bool big_endian, int frame_index) {
    std::string buffer(static_cast<size_t>(num_points) * 12, '\0');
    Read(buffer.data(), static_cast<int64_t>(buffer.size()));
    MatX3d X(num_points, 3);
    const char* p = buffer.data();
    for (int64_t v = 0; v < num_points; ++v) {
      for (int axis = 0; axis < 3; ++axis, p += 4) {
        const float x = GetF32(p, big_endian);
        if (!std::isfinite(x)) {
          ThrowInputError(path_, 0, "point {} of sample {} is {} (not finite)",
                          v, frame_index, x);
        }
        X(v, axis) = x;
      }
    }
    return X;
  }

 private:
  fs::path path_;
  std::ifstream in_;
  int64_t size_ = 0;
};

void CheckTopologyCount(const fs::path& path, const TriMesh* topology,
                        int64_t num_points) {
  if (topology != nullptr && topology->NumVertices() != num_points) {
    ThrowInputError(path, 0,
                    "has {} points per frame, the topology has {} vertices",
                    num_points, topology->NumVertices());
  }
}

// ---------------------------------------------------------------------------
// .pc2: Blender / 3ds Max point cache. Layout as Blender's Mesh Cache
// modifier reads it (MOD_meshcache_pc2.cc): little-endian header
// {char[12] "POINTCACHE2\0", int32 version (1), int32 points, float32 start
// frame, float32 sample rate, int32 samples}, then samples x points x 3
// float32.

void WritePc2(const fs::path& path, const MeshSequence& seq) {
  const int num_points = CheckFrames(path, seq);
  WriteFileAtomic(
      path,
      [&](std::ostream& out) {
        char header[kPc2HeaderBytes];
        std::memcpy(header, kPc2Magic, 12);
        PutU32(header + 12, 1, false);
        PutU32(header + 16, static_cast<uint32_t>(num_points), false);
        PutF32(header + 20, static_cast<float>(seq.start_frame), false);
        PutF32(header + 24, 1.0f, false);
        PutU32(header + 28, static_cast<uint32_t>(seq.frames.size()), false);
        out.write(header, kPc2HeaderBytes);
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
      kPc2HeaderBytes + int64_t{num_samples} * num_points * 12;
  if (file.size() != expected) {
    ThrowInputError(path, 0,
                    "{}: header promises {} samples x {} points ({} bytes), "
                    "the file has {} bytes",
                    file.size() < expected ? "truncated" : "trailing data",
                    num_samples, num_points, expected, file.size());
  }
  CheckTopologyCount(path, options.topology, num_points);

  MeshSequence seq;
  seq.start_frame = options.start_frame.value_or(static_cast<int>(start));
  seq.fps = options.fps > 0 ? options.fps : kDefaultFps;
  seq.frames.reserve(num_samples);
  for (int s = 0; s < num_samples; ++s) {
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

void WriteMdd(const fs::path& path, const MeshSequence& seq) {
  const int num_points = CheckFrames(path, seq);
  WriteFileAtomic(
      path,
      [&](std::ostream& out) {
        const size_t num_frames = seq.frames.size();
        std::string header(8 + 4 * num_frames, '\0');
        PutU32(header.data(), static_cast<uint32_t>(num_frames), true);
        PutU32(header.data() + 4, static_cast<uint32_t>(num_points), true);
        for (size_t f = 0; f < num_frames; ++f) {
          const double time_s =
              (seq.start_frame + static_cast<double>(f)) / seq.fps;
          PutF32(header.data() + 8 + 4 * f, static_cast<float>(time_s), true);
        }
        out.write(header.data(), static_cast<std::streamsize>(header.size()));
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
  const int64_t expected = 8 + int64_t{num_frames} * 4 +
                           int64_t{num_frames} * frame_bytes;
  // Blender's own MDD exporter writes one extra "rest" frame before the
  // frames its header counts; accept it and drop it.
  const bool has_rest_frame = file.size() == expected + frame_bytes;
  if (file.size() != expected && !has_rest_frame) {
    ThrowInputError(path, 0,
                    "{}: header promises {} frames x {} points ({} bytes), "
                    "the file has {} bytes",
                    file.size() < expected ? "truncated" : "trailing data",
                    num_frames, num_points, expected, file.size());
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

// ---------------------------------------------------------------------------
// .usda: one Mesh prim "face", topology and UVs once, `points` time-sampled
// at time codes = frame numbers.

// USD's point3f and texCoord2f hold float32: values are rounded to float32
// and written as the shortest text that reads back as that float (at most 9
// digits), or with fewer digits if `precision` asks for less.
std::string FormatFloat(double x, int precision) {
  const float value = static_cast<float>(x);
  if (precision >= 9) return fmt::format("{}", value);
  return fmt::format("{:.{}g}", value, precision);
}

void WriteUsda(const fs::path& path, const MeshSequence& seq, int precision) {
  const int num_points = CheckFrames(path, seq);
  const TriMesh mesh = TopologyForWrite(path, seq, num_points);
  const int first = seq.start_frame;
  const int last = seq.start_frame + static_cast<int>(seq.frames.size()) - 1;
  WriteFileAtomic(path, [&](std::ostream& out) {
    std::string text;
    auto flush = [&] {
      out.write(text.data(), static_cast<std::streamsize>(text.size()));
      text.clear();
    };
    fmt::format_to(std::back_inserter(text),
                   "#usda 1.0\n"
                   "(\n"
                   "    defaultPrim = \"face\"\n"
                   "    doc = \"hmc mesh sequence (mm, head space, +y up)\"\n"
                   "    endTimeCode = {}\n"
                   "    framesPerSecond = {}\n"
                   "    metersPerUnit = 0.001\n"
                   "    startTimeCode = {}\n"
                   "    timeCodesPerSecond = {}\n"
                   "    upAxis = \"Y\"\n"
                   ")\n\n"
                   "def Mesh \"face\"\n"
                   "{{\n",
                   last, seq.fps, first, seq.fps);
    // Extent per sample: renderers and usdchecker expect it on a Mesh.
    text += "    float3[] extent.timeSamples = {\n";
    for (size_t f = 0; f < seq.frames.size(); ++f) {
      const Eigen::Matrix<double, 2, 3> box = BoundingBox(seq.frames[f]);
      // Rounded outwards to float32, so the box still holds every point.
      Eigen::Matrix<float, 2, 3> box_f = box.cast<float>();
      for (int axis = 0; axis < 3; ++axis) {
        if (box_f(0, axis) > box(0, axis)) {
          box_f(0, axis) = std::nextafter(box_f(0, axis), -INFINITY);
        }
        if (box_f(1, axis) < box(1, axis)) {
          box_f(1, axis) = std::nextafter(box_f(1, axis), INFINITY);
        }
      }
      fmt::format_to(std::back_inserter(text),
                     "        {}: [({}, {}, {}), ({}, {}, {})],\n",
                     first + static_cast<int>(f), box_f(0, 0), box_f(0, 1),
                     box_f(0, 2), box_f(1, 0), box_f(1, 1), box_f(1, 2));
    }
    text += "    }\n";
    text += "    int[] faceVertexCounts = [";
    for (int t = 0; t < mesh.NumFaces(); ++t) text += t ? ", 3" : "3";
    text += "]\n    int[] faceVertexIndices = [";
    for (int t = 0; t < mesh.NumFaces(); ++t) {
      fmt::format_to(std::back_inserter(text), "{}{}, {}, {}", t ? ", " : "",
                     mesh.F(t, 0), mesh.F(t, 1), mesh.F(t, 2));
    }
    text += "]\n    uniform token orientation = \"rightHanded\"\n";
    text += "    point3f[] points.timeSamples = {\n";
    for (size_t f = 0; f < seq.frames.size(); ++f) {
      const MatX3d& X = seq.frames[f];
      fmt::format_to(std::back_inserter(text), "        {}: [",
                     first + static_cast<int>(f));
      for (int v = 0; v < X.rows(); ++v) {
        fmt::format_to(std::back_inserter(text), "{}({}, {}, {})",
                       v ? ", " : "", FormatFloat(X(v, 0), precision),
                       FormatFloat(X(v, 1), precision),
                       FormatFloat(X(v, 2), precision));
        if (text.size() > (1 << 20)) flush();
      }
      text += "],\n";
    }
    text += "    }\n";
    if (mesh.HasUVs()) {
      text += "    texCoord2f[] primvars:st = [";
      for (int i = 0; i < mesh.UV.rows(); ++i) {
        fmt::format_to(std::back_inserter(text), "{}({}, {})", i ? ", " : "",
                       FormatFloat(mesh.UV(i, 0), precision),
                       FormatFloat(mesh.UV(i, 1), precision));
      }
      text += "] (\n        interpolation = \"faceVarying\"\n    )\n";
      text += "    int[] primvars:st:indices = [";
      for (int t = 0; t < mesh.NumFaces(); ++t) {
        fmt::format_to(std::back_inserter(text), "{}{}, {}, {}", t ? ", " : "",
                       mesh.FUV(t, 0), mesh.FUV(t, 1), mesh.FUV(t, 2));
      }
      text += "]\n";
    }
    text += "    uniform token subdivisionScheme = \"none\"\n}\n";
    flush();
  });
}

// Reads the subset of USD ASCII that WriteUsda writes (and close variants:
// any attribute order, polygons fanned into triangles, `points` as a default
// value instead of time samples, st with vertex or faceVarying
// interpolation). Not a general USD parser: the first Mesh's attributes are
// found by name, no composition, no binary crate files.
class UsdaReader {
 public:
  UsdaReader(const fs::path& path, std::string text)
      : path_(path), text_(std::move(text)) {}

  MeshSequence Read(const MeshSequenceReadOptions& options);

 private:
  template <typename... Args>
  [[noreturn]] void Fail(size_t pos, fmt::format_string<Args...> format,
                         Args&&... args) {
    const int line =
        1 + static_cast<int>(std::count(
                text_.begin(),
                text_.begin() + std::min(pos, text_.size()), '\n'));
    ThrowInputError(path_, line, format, std::forward<Args>(args)...);
  }

  // Where the first prim starts: the layer metadata lies before it.
  size_t FindPrimStart() const {
    const size_t at = text_.find("\ndef ");
    return at == std::string::npos ? text_.size() : at;
  }

  void SkipSpace() {
    while (pos_ < text_.size()) {
      const char c = text_[pos_];
      if (c == '#') {
        while (pos_ < text_.size() && text_[pos_] != '\n') ++pos_;
      } else if (std::isspace(static_cast<unsigned char>(c))) {
        ++pos_;
      } else {
        break;
      }
    }
  }
  bool Peek(char c) {
    SkipSpace();
    return pos_ < text_.size() && text_[pos_] == c;
  }
  void Expect(char c, const char* where) {
    if (!Peek(c)) {
      Fail(pos_, "expected '{}' in {}, found '{}'", c, where,
           pos_ < text_.size() ? text_.substr(pos_, 12) : "end of file");
    }
    ++pos_;
  }
  // A number as `Real` (double for metadata and time codes, float for the
  // float32 arrays, so they read back as USD itself would read them).
  template <typename Real = double>
  Real Number(const char* where) {
    SkipSpace();
    const char* begin = text_.data() + pos_;
    const char* end = text_.data() + text_.size();
    if (begin < end && *begin == '+') ++begin;
    Real value = 0;
    const auto [ptr, error] = std::from_chars(begin, end, value);
    if (error != std::errc() || ptr == begin) {
      Fail(pos_, "expected a number in {}", where);
    }
    if (!std::isfinite(value)) Fail(pos_, "non-finite number in {}", where);
    pos_ = static_cast<size_t>(ptr - text_.data());
    return value;
  }
  int Integer(const char* where) {
    const size_t start = pos_;
    const double value = Number(where);
    if (value != std::round(value) || std::abs(value) > 2e9) {
      Fail(start, "expected an integer in {}, found {}", where, value);
    }
    return static_cast<int>(value);
  }

  // Position just after `name =`, where `name` stands alone (not a prefix
  // of a longer name, not preceded by a name character); npos if absent.
  size_t FindAttribute(std::string_view name, size_t from = 0,
                       size_t to = std::string::npos) const {
    size_t at = from;
    while ((at = text_.find(name, at)) != std::string::npos && at < to) {
      const size_t after = at + name.size();
      const bool starts = at == 0 || std::isspace(static_cast<unsigned char>(
                                         text_[at - 1]));
      size_t p = after;
      while (p < text_.size() && (text_[p] == ' ' || text_[p] == '\t')) ++p;
      if (starts && p < text_.size() && text_[p] == '=') return p + 1;
      at = after;
    }
    return std::string::npos;
  }

  std::vector<int> IntArray(const char* where) {
    std::vector<int> values;
    Expect('[', where);
    while (!Peek(']')) {
      values.push_back(Integer(where));
      if (!Peek(']')) Expect(',', where);
    }
    ++pos_;
    return values;
  }

  // [(a, b, ...), ...] of `width`-tuples of float32, flattened.
  std::vector<double> TupleArray(int width, const char* where) {
    std::vector<double> values;
    Expect('[', where);
    while (!Peek(']')) {
      Expect('(', where);
      for (int i = 0; i < width; ++i) {
        if (i > 0) Expect(',', where);
        values.push_back(Number<float>(where));
      }
      Expect(')', where);
      if (!Peek(']')) Expect(',', where);
    }
    ++pos_;
    return values;
  }

  MatX3d Points(const char* where) {
    const size_t start = pos_;
    const std::vector<double> values = TupleArray(3, where);
    if (values.empty()) Fail(start, "{} has no points", where);
    MatX3d X(values.size() / 3, 3);
    std::copy(values.begin(), values.end(), X.data());
    return X;
  }

  fs::path path_;
  std::string text_;
  size_t pos_ = 0;
};

MeshSequence UsdaReader::Read(const MeshSequenceReadOptions& options) {
  if (text_.rfind("#usda ", 0) != 0) {
    Fail(0, "not a USD ASCII file (does not start with '#usda 1.0')");
  }
  // Layer metadata: the parenthesised block before the first prim.
  const size_t first_def = FindPrimStart();
  MeshSequence seq;
  double start_time_code = 1;
  if (size_t at = FindAttribute("startTimeCode", 0, first_def);
      at != std::string::npos) {
    pos_ = at;
    start_time_code = Number("startTimeCode");
  }
  double fps = 0;
  for (const char* key : {"framesPerSecond", "timeCodesPerSecond"}) {
    // timeCodesPerSecond maps time codes to seconds; it wins if both exist.
    if (size_t at = FindAttribute(key, 0, first_def);
        at != std::string::npos) {
      pos_ = at;
      fps = Number(key);
      if (!(fps > 0)) Fail(at, "{} must be positive", key);
    }
  }
  seq.fps = options.fps > 0 ? options.fps : fps > 0 ? fps : 24.0;  // USD's
                                                                   // default

  const size_t mesh_at = text_.find("def Mesh", first_def);
  if (mesh_at == std::string::npos) Fail(first_def, "no Mesh prim");

  // Points: time samples keyed by frame number, or one default value.
  std::vector<std::pair<double, MatX3d>> samples;
  if (size_t at = FindAttribute("points.timeSamples", mesh_at);
      at != std::string::npos) {
    pos_ = at;
    Expect('{', "points.timeSamples");
    while (!Peek('}')) {
      const size_t key_at = pos_;
      const double key = Number("points.timeSamples");
      Expect(':', "points.timeSamples");
      samples.emplace_back(key, Points("points.timeSamples"));
      if (samples.back().second.rows() != samples.front().second.rows()) {
        Fail(key_at, "sample {} has {} points, sample {} has {}", key,
             samples.back().second.rows(), samples.front().first,
             samples.front().second.rows());
      }
      if (!Peek('}')) Expect(',', "points.timeSamples");
    }
    std::stable_sort(samples.begin(), samples.end(),
                     [](const auto& a, const auto& b) {
                       return a.first < b.first;
                     });
    for (size_t i = 0; i < samples.size(); ++i) {
      if (samples[i].first != samples[0].first + static_cast<double>(i) ||
          samples[i].first != std::round(samples[i].first)) {
        Fail(at,
             "points.timeSamples must be at consecutive whole time codes "
             "(one per frame); found {} after {}",
             samples[i].first, i ? samples[i - 1].first : samples[0].first);
      }
    }
  } else if (size_t at = FindAttribute("points", mesh_at);
             at != std::string::npos) {
    pos_ = at;
    samples.emplace_back(start_time_code, Points("points"));
  }
  if (samples.empty()) Fail(mesh_at, "the Mesh has no points");
  if (std::abs(samples[0].first) > kMaxFrameNumber) {
    Fail(mesh_at, "time code {} is out of range", samples[0].first);
  }
  seq.start_frame =
      options.start_frame.value_or(static_cast<int>(samples[0].first));
  const int num_points = static_cast<int>(samples[0].second.rows());
  for (auto& sample : samples) seq.frames.push_back(std::move(sample.second));

  // Topology.
  const size_t counts_at = FindAttribute("faceVertexCounts", mesh_at);
  const size_t indices_at = FindAttribute("faceVertexIndices", mesh_at);
  if (counts_at == std::string::npos || indices_at == std::string::npos) {
    Fail(mesh_at, "the Mesh lacks faceVertexCounts or faceVertexIndices");
  }
  pos_ = counts_at;
  const std::vector<int> counts = IntArray("faceVertexCounts");
  pos_ = indices_at;
  const std::vector<int> indices = IntArray("faceVertexIndices");
  int64_t corners = 0;
  int64_t triangles = 0;
  for (int count : counts) {
    if (count < 3) Fail(counts_at, "a face has {} corners (< 3)", count);
    corners += count;
    triangles += count - 2;
  }
  if (corners != static_cast<int64_t>(indices.size())) {
    Fail(indices_at, "faceVertexIndices has {} entries, faceVertexCounts "
         "sums to {}", indices.size(), corners);
  }
  for (int index : indices) {
    if (index < 0 || index >= num_points) {
      Fail(indices_at, "vertex index {} outside 0..{}", index,
           num_points - 1);
    }
  }
  // Polygons fanned from their first corner, as ReadObj does.
  auto fan = [&](const std::vector<int>& corner_values, MatX3i* out) {
    out->resize(triangles, 3);
    int64_t corner = 0;
    int64_t t = 0;
    for (int count : counts) {
      for (int j = 1; j + 1 < count; ++j, ++t) {
        (*out)(t, 0) = corner_values[corner];
        (*out)(t, 1) = corner_values[corner + j];
        (*out)(t, 2) = corner_values[corner + j + 1];
      }
      corner += count;
    }
  };
  fan(indices, &seq.topology.F);

  if (size_t st_at = FindAttribute("primvars:st", mesh_at);
      st_at != std::string::npos) {
    pos_ = st_at;
    const std::vector<double> st = TupleArray(2, "primvars:st");
    const int num_uvs = static_cast<int>(st.size() / 2);
    seq.topology.UV.resize(num_uvs, 2);
    std::copy(st.begin(), st.end(), seq.topology.UV.data());
    std::string interpolation = "constant";
    if (Peek('(')) {
      const size_t close = text_.find(')', pos_);
      const size_t at = FindAttribute("interpolation", pos_, close);
      if (at != std::string::npos) {
        const size_t open_quote = text_.find('"', at);
        const size_t close_quote = text_.find('"', open_quote + 1);
        if (close_quote < close) {
          interpolation =
              text_.substr(open_quote + 1, close_quote - open_quote - 1);
        }
      }
    }
    std::vector<int> uv_of_corner;
    if (size_t at = FindAttribute("primvars:st:indices", mesh_at);
        at != std::string::npos) {
      pos_ = at;
      uv_of_corner = IntArray("primvars:st:indices");
      if (interpolation == "vertex") {
        Fail(at, "indexed primvars:st with vertex interpolation is not "
             "supported");
      }
    } else if (interpolation == "vertex" && num_uvs == num_points) {
      uv_of_corner = indices;
    } else {
      uv_of_corner.resize(static_cast<size_t>(corners));
      for (int64_t i = 0; i < corners; ++i) uv_of_corner[i] = i;
    }
    if (interpolation != "faceVarying" && interpolation != "vertex") {
      Fail(st_at, "primvars:st interpolation '{}' is not supported "
           "(faceVarying or vertex)", interpolation);
    }
    if (static_cast<int64_t>(uv_of_corner.size()) != corners) {
      Fail(st_at, "primvars:st has {} corner entries, the faces have {}",
           uv_of_corner.size(), corners);
    }
    for (int index : uv_of_corner) {
      if (index < 0 || index >= num_uvs) {
        Fail(st_at, "UV index {} outside 0..{}", index, num_uvs - 1);
      }
    }
    fan(uv_of_corner, &seq.topology.FUV);
  }
  seq.topology.V = seq.frames[0];
  return seq;
}

// ---------------------------------------------------------------------------
// OBJ folder: frame_000001.obj, ... written into a temporary sibling folder
// and renamed into place.

std::string ObjFrameName(int frame) {
  return fmt::format("frame_{:06d}.obj", frame);
}

// The frame number of "frame_<digits>.obj", or nullopt.
std::optional<int> ObjFrameNumber(const std::string& name) {
  constexpr std::string_view kPrefix = "frame_";
  constexpr std::string_view kSuffix = ".obj";
  if (name.size() <= kPrefix.size() + kSuffix.size() ||
      name.compare(0, kPrefix.size(), kPrefix) != 0 ||
      name.compare(name.size() - kSuffix.size(), kSuffix.size(), kSuffix) !=
          0) {
    return std::nullopt;
  }
  const char* begin = name.data() + kPrefix.size();
  const char* end = name.data() + name.size() - kSuffix.size();
  int frame = 0;
  const auto [ptr, error] = std::from_chars(begin, end, frame);
  if (error != std::errc() || ptr != end) return std::nullopt;
  return frame;
}

// Runs body(i) for every i in parallel; rethrows the exception of the lowest
// failing index, so the error does not depend on the thread count.
template <typename Body>
void ParallelForFirstError(int64_t n, const Body& body) {
  std::vector<std::exception_ptr> errors(n);
  ParallelFor(0, n, [&](int64_t i) {
    try {
      body(i);
    } catch (...) {
      errors[i] = std::current_exception();
    }
  });
  for (const std::exception_ptr& error : errors) {
    if (error) std::rethrow_exception(error);
  }
}

fs::path WithoutTrailingSlash(const fs::path& path) {
  return path.has_filename() ? path : path.parent_path();
}

void WriteObjFolder(const fs::path& path_in, const MeshSequence& seq,
                    int precision) {
  const fs::path path = WithoutTrailingSlash(path_in);
  const int num_points = CheckFrames(path, seq);
  const TriMesh mesh = TopologyForWrite(path, seq, num_points);
  const fs::path parent = path.has_parent_path() ? path.parent_path() : ".";
  if (!fs::is_directory(parent)) {
    ThrowInputError(path, 0, "cannot write: folder {} does not exist",
                    parent.string());
  }
  // Replacing a folder deletes it, so only ever replace one that holds
  // nothing but frames we could have written.
  if (fs::exists(path)) {
    if (!fs::is_directory(path)) {
      ThrowInputError(path, 0,
                      "cannot write an OBJ folder: a file of that name exists");
    }
    for (const fs::directory_entry& entry : fs::directory_iterator(path)) {
      if (!entry.is_regular_file() ||
          !ObjFrameNumber(entry.path().filename().string())) {
        ThrowInputError(path, 0,
                        "not replacing this folder: it holds {}, which is not "
                        "an OBJ frame (frame_NNNNNN.obj)",
                        entry.path().filename().string());
      }
    }
  }

  static std::atomic<int> counter{0};
  const std::string stem = path.filename().string();
  const int id = counter++;
  const fs::path temp =
      parent / fmt::format(".{}.tmp.{}.{}", stem, getpid(), id);
  const fs::path old = parent / fmt::format(".{}.old.{}.{}", stem, getpid(), id);
  try {
    EnsureDirectory(temp);
    ParallelForFirstError(static_cast<int64_t>(seq.frames.size()),
                          [&](int64_t f) {
                            WriteObj(temp / ObjFrameName(seq.start_frame +
                                                         static_cast<int>(f)),
                                     mesh, seq.frames[f], precision);
                          });
    std::error_code error;
    const bool replacing = fs::exists(path);
    if (replacing) {
      fs::rename(path, old, error);
      if (error) {
        ThrowInputError(path, 0, "cannot move the previous folder aside: {}",
                        error.message());
      }
    }
    fs::rename(temp, path, error);
    if (error) {
      std::error_code ignored;
      if (replacing) fs::rename(old, path, ignored);  // put it back
      ThrowInputError(path, 0, "cannot rename the temporary folder: {}",
                      error.message());
    }
    if (replacing) fs::remove_all(old, error);
  } catch (...) {
    std::error_code ignored;
    fs::remove_all(temp, ignored);
    throw;
  }
}

MeshSequence ReadObjFolder(const fs::path& path_in,
                           const MeshSequenceReadOptions& options) {
  const fs::path path = WithoutTrailingSlash(path_in);
  if (!fs::is_directory(path)) {
    ThrowInputError(path, 0, fs::exists(path)
                                 ? "not a folder (an OBJ sequence is a folder "
                                   "of frame_NNNNNN.obj)"
                                 : "folder does not exist");
  }
  std::vector<std::pair<int, fs::path>> files;
  for (const fs::directory_entry& entry : fs::directory_iterator(path)) {
    const std::optional<int> frame =
        ObjFrameNumber(entry.path().filename().string());
    if (frame && entry.is_regular_file()) files.emplace_back(*frame, entry);
  }
  if (files.empty()) {
    ThrowInputError(path, 0, "no OBJ frames (frame_NNNNNN.obj) in the folder");
  }
  std::sort(files.begin(), files.end());
  for (size_t i = 1; i < files.size(); ++i) {
    if (files[i].first == files[i - 1].first) {
      ThrowInputError(path, 0, "frame {} appears twice ({} and {})",
                      files[i].first, files[i - 1].second.filename().string(),
                      files[i].second.filename().string());
    }
    if (files[i].first != files[i - 1].first + 1) {
      ThrowInputError(path, 0, "frame {} is missing (between {} and {})",
                      files[i - 1].first + 1,
                      files[i - 1].second.filename().string(),
                      files[i].second.filename().string());
    }
  }
  std::vector<TriMesh> meshes(files.size());
  ParallelForFirstError(static_cast<int64_t>(files.size()), [&](int64_t i) {
    meshes[i] = ReadObj(files[i].second);
  });
  const TriMesh& first = meshes[0];
  for (size_t i = 1; i < meshes.size(); ++i) {
    const TriMesh& mesh = meshes[i];
    if (mesh.NumVertices() != first.NumVertices() || mesh.F != first.F ||
        mesh.UV.rows() != first.UV.rows() || mesh.UV != first.UV ||
        mesh.FUV != first.FUV) {
      ThrowInputError(files[i].second, 0,
                      "topology (vertex count, faces or UVs) differs from {}",
                      files[0].second.filename().string());
    }
  }
  MeshSequence seq;
  seq.start_frame = options.start_frame.value_or(files[0].first);
  seq.fps = options.fps > 0 ? options.fps : kDefaultFps;
  seq.topology = first;
  seq.frames.reserve(meshes.size());
  for (TriMesh& mesh : meshes) seq.frames.push_back(std::move(mesh.V));
  return seq;
}

}  // namespace

SequenceFormat SequenceFormatFromPath(const fs::path& path) {
  if (fs::is_directory(path)) return SequenceFormat::kObjFolder;
  std::string ext = WithoutTrailingSlash(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  if (ext.empty()) return SequenceFormat::kObjFolder;
  if (ext == ".pc2") return SequenceFormat::kPc2;
  if (ext == ".mdd") return SequenceFormat::kMdd;
  if (ext == ".usda") return SequenceFormat::kUsda;
  if (ext == ".usd" || ext == ".usdc" || ext == ".usdz") {
    ThrowInputError(path, 0,
                    "binary USD ({}) is not supported: use .usda (USD ASCII)",
                    ext);
  }
  ThrowInputError(path, 0,
                  "unknown mesh sequence extension '{}' (.pc2, .mdd, .usda, "
                  "or a folder name without extension for OBJ frames)",
                  ext);
}

bool SequenceFormatHasTopology(SequenceFormat format) {
  return format == SequenceFormat::kUsda ||
         format == SequenceFormat::kObjFolder;
}

MeshSequence ReadMeshSequence(const fs::path& path, const TriMesh* topology) {
  MeshSequenceReadOptions options;
  options.topology = topology;
  return ReadMeshSequence(path, options);
}

MeshSequence ReadMeshSequence(const fs::path& path,
                              const MeshSequenceReadOptions& options) {
  if (options.fps < 0 || !std::isfinite(options.fps)) {
    throw InputError(fmt::format("frame rate {} must be positive", options.fps));
  }
  switch (SequenceFormatFromPath(path)) {
    case SequenceFormat::kPc2:
      return ReadPc2(path, options);
    case SequenceFormat::kMdd:
      return ReadMdd(path, options);
    case SequenceFormat::kUsda:
      return UsdaReader(path, ReadFile(path)).Read(options);
    case SequenceFormat::kObjFolder:
      return ReadObjFolder(path, options);
  }
  HMC_CHECK(false);
  return {};
}

void WriteMeshSequence(const fs::path& path, const MeshSequence& seq,
                       int precision) {
  if (precision < 1 || precision > 17) {
    ThrowInputError(path, 0, "precision {} outside 1..17 digits", precision);
  }
  switch (SequenceFormatFromPath(path)) {
    case SequenceFormat::kPc2:
      return WritePc2(path, seq);
    case SequenceFormat::kMdd:
      return WriteMdd(path, seq);
    case SequenceFormat::kUsda:
      return WriteUsda(path, seq, precision);
    case SequenceFormat::kObjFolder:
      return WriteObjFolder(path, seq, precision);
  }
}

}  // namespace hmc
