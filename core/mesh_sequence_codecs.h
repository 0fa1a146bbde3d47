// The codecs behind core/mesh_sequence.h, one file per format family:
// mesh_sequence_pc2_mdd.cc (the binary point caches), mesh_sequence_usda.cc
// (USD ASCII writer and parser), mesh_sequence_obj.cc (OBJ frame folders),
// and what they share (mesh_sequence_codecs.cc: validation before a write,
// explicit-byte-order binary helpers). Internal to core/: only
// mesh_sequence.cc's dispatch calls them.
#pragma once

#include <cstdint>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <ostream>
#include <string>

#include "core/error.h"
#include "core/mesh_sequence.h"

namespace hmc::sequence_io {

namespace fs = std::filesystem;

constexpr double kDefaultFps = 30.0;
constexpr char kPc2Magic[12] = {'P', 'O', 'I', 'N', 'T', 'C', 'A',
                                'C', 'H', 'E', '2', '\0'};
constexpr int64_t kPc2HeaderBytes = 32;  // magic, version, points, start,
                                         // sample rate, samples
// Frame numbers and the PC2 start frame travel as float32, exact up to 2^24.
constexpr int kMaxFrameNumber = 1 << 24;

// Checks what every format needs: at least one frame, one vertex count, and
// values a float32 file can hold (all formats are float32 in the DCCs that
// read them). Returns the vertex count.
int CheckFrames(const fs::path& path, const MeshSequence& seq);
// Its two parts, for a writer that gets its frames one at a time: the
// sequence's size and numbering, and one frame (frame_number: for the
// message; start_frame: the frame that set num_points).
void CheckSequenceHeader(const fs::path& path, int64_t num_frames,
                         int64_t num_points, int start_frame, double fps);
void CheckFrameValues(const fs::path& path, const MatX3d& X,
                      int64_t frame_number, int64_t num_points,
                      int start_frame);
// The topology a writer that stores one may write (seq.topology, checked
// against num_points).
TriMesh TopologyForWrite(const fs::path& path, const MeshSequence& seq,
                         int num_points);

// Binary helpers: explicit byte order, independent of the host's.
void PutU32(char* out, uint32_t value, bool big_endian);
uint32_t GetU32(const char* in, bool big_endian);
void PutF32(char* out, float value, bool big_endian);
float GetF32(const char* in, bool big_endian);
int32_t GetI32(const char* in, bool big_endian);
// Writes each frame as V x 3 float32.
void WriteFramesF32(std::ostream& out, const MeshSequence& seq,
                    bool big_endian);
// One frame of it (buffer: reused between frames).
void WriteFrameF32(std::ostream& out, const MatX3d& X, bool big_endian,
                   std::string* buffer);

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
  const fs::path& path() const { return path_; }

  void Read(char* out, int64_t bytes) {
    in_.read(out, bytes);
    if (in_.gcount() != bytes) {
      ThrowInputError(path_, 0, "read failed (file shrank while reading?)");
    }
  }
  // Passes over `bytes` (the size was checked against the header).
  void Skip(int64_t bytes) {
    in_.seekg(bytes, std::ios::cur);
    if (!in_) ThrowInputError(path_, 0, "seek failed (file shrank while reading?)");
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
                        int64_t num_points);

// The codecs.
void WritePc2(const fs::path& path, const MeshSequence& seq);
// The headers of the two point caches (frames follow as WriteFrameF32).
void WritePc2Header(std::ostream& out, int num_points, int start_frame,
                    int64_t num_frames);
void WriteMddHeader(std::ostream& out, int num_points, int start_frame,
                    int64_t num_frames, double fps);
MeshSequence ReadPc2(const fs::path& path,
                     const MeshSequenceReadOptions& options);
void WriteMdd(const fs::path& path, const MeshSequence& seq);
MeshSequence ReadMdd(const fs::path& path,
                     const MeshSequenceReadOptions& options);
void WriteUsda(const fs::path& path, const MeshSequence& seq, int precision);
MeshSequence ReadUsda(const fs::path& path,
                      const MeshSequenceReadOptions& options);
void WriteObjFolder(const fs::path& path, const MeshSequence& seq,
                    int precision);
MeshSequence ReadObjFolder(const fs::path& path,
                           const MeshSequenceReadOptions& options);
// "dir/" -> "dir" (an OBJ folder may be named with a trailing slash).
fs::path WithoutTrailingSlash(const fs::path& path);

}  // namespace hmc::sequence_io
