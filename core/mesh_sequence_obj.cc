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


}  // namespace hmc::sequence_io
