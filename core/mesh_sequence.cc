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
#include "core/mesh_sequence_codecs.h"

namespace hmc {

namespace fs = std::filesystem;

SequenceFormat SequenceFormatFromPath(const fs::path& path) {
  if (fs::is_directory(path)) return SequenceFormat::kObjFolder;
  std::string ext = sequence_io::WithoutTrailingSlash(path).extension().string();
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
  MeshSequence seq;
  switch (SequenceFormatFromPath(path)) {
    case SequenceFormat::kPc2:
      return sequence_io::ReadPc2(path, options);  // skips unwanted frames itself
    case SequenceFormat::kMdd:
      seq = sequence_io::ReadMdd(path, options);
      break;
    case SequenceFormat::kUsda:
      seq = sequence_io::ReadUsda(path, options);
      break;
    case SequenceFormat::kObjFolder:
      seq = sequence_io::ReadObjFolder(path, options);
      break;
  }
  if (options.wanted) {
    for (size_t f = 0; f < seq.frames.size(); ++f) {
      if (!options.wanted(seq.start_frame + static_cast<int>(f))) seq.frames[f] = MatX3d();
    }
  }
  return seq;
}

void WriteMeshSequence(const fs::path& path, const MeshSequence& seq,
                       int precision) {
  if (precision < 1 || precision > 17) {
    ThrowInputError(path, 0, "precision {} outside 1..17 digits", precision);
  }
  switch (SequenceFormatFromPath(path)) {
    case SequenceFormat::kPc2:
      return sequence_io::WritePc2(path, seq);
    case SequenceFormat::kMdd:
      return sequence_io::WriteMdd(path, seq);
    case SequenceFormat::kUsda:
      return sequence_io::WriteUsda(path, seq, precision);
    case SequenceFormat::kObjFolder:
      return sequence_io::WriteObjFolder(path, seq, precision);
  }
}

bool SequenceFormatStreams(SequenceFormat format) {
  return format == SequenceFormat::kPc2 || format == SequenceFormat::kMdd;
}

void WriteMeshSequenceStreamed(const fs::path& path, int64_t num_frames,
                               int num_points, int start_frame, double fps,
                               const std::function<void(const EmitMesh& emit)>& produce) {
  const SequenceFormat format = SequenceFormatFromPath(path);
  if (!SequenceFormatStreams(format)) {
    ThrowInputError(path, 0, "only .pc2 and .mdd are written frame by frame");
  }
  const bool big_endian = format == SequenceFormat::kMdd;
  sequence_io::CheckSequenceHeader(path, num_frames, num_points, start_frame, fps);
  WriteFileAtomic(
      path,
      [&](std::ostream& out) {
        if (big_endian) {
          sequence_io::WriteMddHeader(out, num_points, start_frame, num_frames, fps);
        } else {
          sequence_io::WritePc2Header(out, num_points, start_frame, num_frames);
        }
        std::string buffer;
        int64_t written = 0;
        produce([&](const MatX3d& mesh) {
          if (written >= num_frames) {
            ThrowInputError(path, 0, "cannot write: more than the {} frames announced",
                            num_frames);
          }
          sequence_io::CheckFrameValues(path, mesh, start_frame + written, num_points,
                                        start_frame);
          sequence_io::WriteFrameF32(out, mesh, big_endian, &buffer);
          ++written;
        });
        if (written != num_frames) {
          ThrowInputError(path, 0, "cannot write: {} of the {} frames announced came",
                          written, num_frames);
        }
      },
      /*binary=*/true);
}

}  // namespace hmc
