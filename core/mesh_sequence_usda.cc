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
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "core/error.h"
#include "core/file_util.h"
#include "core/obj_io.h"
#include "core/parallel.h"
#include "core/usd_text.h"

namespace hmc::sequence_io {
// ---------------------------------------------------------------------------
// .usda: one Mesh prim "face", topology and UVs once, `points` time-sampled
// at time codes = frame numbers.

// One frame's `points` time sample, "        F: [(x, y, z), ...],\n".
std::string PointsSample(int frame, const MatX3d& X, int precision) {
  std::string text;
  text.reserve(static_cast<size_t>(X.rows()) * 36 + 32);
  fmt::format_to(std::back_inserter(text), "        {}: [", frame);
  for (int v = 0; v < X.rows(); ++v) {
    text += v ? ", (" : "(";
    AppendUsdFloat(&text, X(v, 0), precision);
    text += ", ";
    AppendUsdFloat(&text, X(v, 1), precision);
    text += ", ";
    AppendUsdFloat(&text, X(v, 2), precision);
    text += ')';
  }
  text += "],\n";
  return text;
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
    AppendUsdStageHeader(&text, "face", "hmc mesh sequence (mm, head space, +y up)", first, last,
                         seq.fps, seq.timecode);
    text += "def Mesh \"face\"\n{\n";
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
    AppendUsdFaces(&text, mesh, "    ");
    text += "    point3f[] points.timeSamples = {\n";
    flush();
    // The frames' text formatted side by side, a batch at a time (bounded
    // memory), written in order: the same bytes as one after the other.
    constexpr int64_t kBatch = 16;
    const int64_t F = static_cast<int64_t>(seq.frames.size());
    std::vector<std::string> batch(kBatch);
    for (int64_t begin = 0; begin < F; begin += kBatch) {
      const int64_t end = std::min(F, begin + kBatch);
      ParallelFor(begin, end, [&](int64_t f) {
        batch[f - begin] = PointsSample(first + static_cast<int>(f), seq.frames[f], precision);
      });
      for (int64_t f = begin; f < end; ++f) {
        out.write(batch[f - begin].data(), static_cast<std::streamsize>(batch[f - begin].size()));
      }
    }
    text += "    }\n";
    AppendUsdUvs(&text, mesh, "    ", precision);
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
  if (size_t at = FindAttribute("timecode", 0, first_def); at != std::string::npos) {
    // `string timecode = "HH:MM:SS:FF"` of the custom layer data.
    pos_ = at;
    Expect('"', "timecode");
    const size_t end = text_.find('"', pos_);
    if (end == std::string::npos || end > first_def) Fail(at, "timecode: no closing quote");
    seq.timecode = text_.substr(pos_, end - pos_);
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


MeshSequence ReadUsda(const fs::path& path,
                      const MeshSequenceReadOptions& options) {
  return UsdaReader(path, ReadFile(path)).Read(options);
}

}  // namespace hmc::sequence_io
