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
// ---------------------------------------------------------------------------
// Validation shared by the writers.

// Checks what every format needs: at least one frame, one vertex count, and
// values a float32 file can hold (all formats are float32 in the DCCs that
// read them). Returns the vertex count.
void CheckSequenceHeader(const fs::path& path, int64_t num_frames,
                         int64_t num_points, int start_frame, double fps) {
  if (num_frames <= 0) {
    ThrowInputError(path, 0, "cannot write a mesh sequence with no frames");
  }
  if (num_points <= 0) {
    ThrowInputError(path, 0, "cannot write a mesh sequence with no vertices");
  }
  if (!(fps > 0) || !std::isfinite(fps)) {
    ThrowInputError(path, 0, "cannot write: frame rate {} is not positive",
                    fps);
  }
  const int64_t last_frame = static_cast<int64_t>(start_frame) + num_frames - 1;
  if (std::abs(static_cast<int64_t>(start_frame)) > kMaxFrameNumber ||
      std::abs(last_frame) > kMaxFrameNumber) {
    ThrowInputError(path, 0,
                    "cannot write: frame numbers {}..{} exceed +-{} (float32 "
                    "frame numbers)",
                    start_frame, last_frame, kMaxFrameNumber);
  }
}

void CheckFrameValues(const fs::path& path, const MatX3d& X,
                      int64_t frame_number, int64_t num_points,
                      int start_frame) {
  constexpr double kFloatMax = std::numeric_limits<float>::max();
  if (X.rows() != num_points) {
    ThrowInputError(path, 0,
                    "cannot write: frame {} has {} vertices, frame {} has {}",
                    frame_number, X.rows(), start_frame, num_points);
  }
  for (int64_t v = 0; v < X.rows(); ++v) {
    for (int axis = 0; axis < 3; ++axis) {
      const double x = X(v, axis);
      if (!std::isfinite(x) || std::abs(x) > kFloatMax) {
        ThrowInputError(path, 0,
                        "cannot write: vertex {} of frame {} is {} (not a "
                        "finite float32)",
                        v, frame_number, x);
      }
    }
  }
}

int CheckFrames(const fs::path& path, const MeshSequence& seq) {
  const int64_t num_points = seq.frames.empty() ? 0 : seq.frames[0].rows();
  if (seq.frames.empty()) {
    ThrowInputError(path, 0, "cannot write a mesh sequence with no frames");
  }
  CheckSequenceHeader(path, static_cast<int64_t>(seq.frames.size()), num_points,
                      seq.start_frame, seq.fps);
  for (size_t f = 0; f < seq.frames.size(); ++f) {
    CheckFrameValues(path, seq.frames[f],
                     seq.start_frame + static_cast<int64_t>(f), num_points,
                     seq.start_frame);
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
void WriteFrameF32(std::ostream& out, const MatX3d& X, bool big_endian,
                   std::string* buffer) {
  buffer->resize(static_cast<size_t>(X.rows()) * 12);
  char* p = buffer->data();
  for (int64_t v = 0; v < X.rows(); ++v) {
    for (int axis = 0; axis < 3; ++axis, p += 4) {
      PutF32(p, static_cast<float>(X(v, axis)), big_endian);
    }
  }
  out.write(buffer->data(), static_cast<std::streamsize>(buffer->size()));
}

void WriteFramesF32(std::ostream& out, const MeshSequence& seq,
                    bool big_endian) {
  std::string buffer;
  for (const MatX3d& X : seq.frames) WriteFrameF32(out, X, big_endian, &buffer);
}

void CheckTopologyCount(const fs::path& path, const TriMesh* topology,
                        int64_t num_points) {
  if (topology != nullptr && topology->NumVertices() != num_points) {
    ThrowInputError(path, 0,
                    "has {} points per frame, the topology has {} vertices",
                    num_points, topology->NumVertices());
  }
}


}  // namespace hmc::sequence_io
