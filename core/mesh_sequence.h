// Mesh sequences (docs/formats.md): one topology, many frames of vertex
// positions. Formats, chosen by extension:
//   .pc2   Blender / 3ds Max point cache (float32, little endian)
//   .mdd   LightWave / Blender MDD (float32, big endian, with frame times)
//   .usda  USD ASCII: topology and UVs once, time-sampled `points`
//   folder (no extension): one OBJ per frame, frame_000001.obj, ...
// All writes are atomic. Formats: docs/formats.md.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "core/mesh.h"

namespace hmc {

struct MeshSequence {
  std::vector<MatX3d> frames;  // each V x 3 (mm)
  int start_frame = 1;         // number of frames[0]
  double fps = 30.0;           // frames per second
  std::string timecode;        // SMPTE timecode of frames[0] ("" if none):
                               // .usda keeps it (customLayerData), the
                               // other formats have no place for it
  TriMesh topology;            // triangles (+ UVs); V may be empty for .pc2/.mdd
                               // when the topology is read from elsewhere
};

enum class SequenceFormat { kPc2, kMdd, kUsda, kObjFolder };

// By extension of `path`; a path without extension is an OBJ folder. Throws
// InputError for an unknown extension.
SequenceFormat SequenceFormatFromPath(const std::filesystem::path& path);

// Reads any format. For .pc2/.mdd (points only) the topology is empty
// unless `topology` is given; its vertex count is then checked.
MeshSequence ReadMeshSequence(const std::filesystem::path& path,
                              const TriMesh* topology = nullptr);

// What a file may not carry, given by the caller (`hmc convert --fps`).
struct MeshSequenceReadOptions {
  // For .pc2/.mdd (points only): triangles and UVs; vertex count checked.
  const TriMesh* topology = nullptr;
  // > 0: frames per second, overriding the file's; for .mdd it also numbers
  // the frames from their times. 0: the file's (.usda, .mdd with two or more
  // frames), else 30 (.usda without a rate: USD's default, 24).
  double fps = 0.0;
  // Number of the first frame, overriding the file's (.pc2 start, .mdd first
  // time, .usda time codes, OBJ file names).
  std::optional<int> start_frame;
  // Frame number -> whether to load its points (null: every frame). A
  // frame not wanted comes back empty (0 x 3): a long sequence's few
  // frames without holding the rest (a .pc2 does not read them at all).
  std::function<bool(int)> wanted;
};
MeshSequence ReadMeshSequence(const std::filesystem::path& path,
                              const MeshSequenceReadOptions& options);

// True for the formats that store triangles and UVs (.usda, OBJ folder).
bool SequenceFormatHasTopology(SequenceFormat format);

// Writes any format. .usda and OBJ folders need seq.topology; .pc2/.mdd do
// not. `precision`: significant digits for OBJ frames (17 round-trips any
// double). .pc2/.mdd/.usda hold float32 (.usda: point3f, texCoord2f): values
// are rounded to float32, and .usda writes the shortest text that reads back
// as that float (fewer digits if precision < 9).
void WriteMeshSequence(const std::filesystem::path& path,
                       const MeshSequence& seq, int precision = 9);

// True for the formats WriteMeshSequenceStreamed writes (.pc2, .mdd: the
// point caches, whose header needs only the counts).
bool SequenceFormatStreams(SequenceFormat format);

// Writes a .pc2 or .mdd whose frames come one at a time, so a long
// sequence is never held whole (issue 46: the solve writes each mesh as it
// is final). The header is written first from num_frames, num_points,
// start_frame and fps; then produce(emit) runs and must call emit(mesh)
// once per frame, in order (V x 3, mm; rounded to float32 as written, so
// the bytes equal WriteMeshSequence's of the same frames). Atomic as
// WriteMeshSequence: the frames go to a temporary file renamed at the end;
// a frame it would refuse (vertex count, non-finite or beyond float32),
// another number of frames than num_frames, or an exception from produce
// leaves nothing and the previous file as it was.
using EmitMesh = std::function<void(const MatX3d& mesh)>;
void WriteMeshSequenceStreamed(const std::filesystem::path& path, int64_t num_frames,
                               int num_points, int start_frame, double fps,
                               const std::function<void(const EmitMesh& emit)>& produce);

}  // namespace hmc
