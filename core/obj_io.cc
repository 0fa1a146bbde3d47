#include "core/obj_io.h"

#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>

#include <fmt/format.h>

#include "core/error.h"
#include "core/file_util.h"
#include "core/text.h"

namespace hmc {
namespace {

bool IsBlank(char c) {
  return c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v';
}

// Next whitespace-separated token of [*p, end); empty at the end of the line.
std::string_view NextToken(const char*& p, const char* end) {
  while (p < end && IsBlank(*p)) ++p;
  const char* start = p;
  while (p < end && !IsBlank(*p)) ++p;
  return std::string_view(start, static_cast<size_t>(p - start));
}

// Statements of the OBJ specification that carry nothing hmc uses: normals
// (recomputed from the triangles), groups, smoothing, materials, free-form
// geometry. Anything else is a broken or truncated file.
bool IsIgnoredStatement(std::string_view keyword) {
  static const char* const kIgnored[] = {
      "vn",    "vp",   "g",     "o",        "s",        "usemtl", "mtllib",
      "l",     "p",    "cstype", "deg",     "bmat",     "step",   "curv",
      "curv2", "surf", "parm",  "trim",     "hole",     "scrv",   "sp",
      "end",   "con",  "mg",    "bevel",    "c_interp", "d_interp", "lod",
      "maplib", "usemap", "shadow_obj", "trace_obj", "ctech", "stech", "call",
      "csh"};
  for (const char* ignored : kIgnored) {
    if (keyword == ignored) return true;
  }
  return false;
}

class ObjParser {
 public:
  ObjParser(std::string_view text, const std::filesystem::path& origin,
            const ObjReadOptions& options)
      : text_(text), origin_(origin), options_(options) {}

  TriMesh Parse(ObjPolygons* polygons);

 private:
  template <typename... Args>
  [[noreturn]] void Fail(fmt::format_string<Args...> format, Args&&... args) {
    ThrowInputError(origin_, line_, format, std::forward<Args>(args)...);
  }

  void ParseVertex(const char* p, const char* end);
  void ParseTexCoord(const char* p, const char* end);
  void ParseFace(const char* p, const char* end);
  // Resolves a 1-based or negative (relative) OBJ index against `count`
  // elements defined so far; returns the 0-based index.
  int ResolveIndex(long long index, long long count, const char* what,
                   std::string_view token);

  std::string_view text_;
  const std::filesystem::path& origin_;
  const ObjReadOptions& options_;
  int line_ = 0;

  std::vector<double> positions_;  // 3 per `v`
  std::vector<double> uvs_;        // 2 per `vt`
  long long num_normals_ = 0;
  std::vector<int> corner_v_;      // all polygon corners, in order
  std::vector<int> corner_vt_;     // same length when faces have UVs
  std::vector<int> polygon_begin_;  // P + 1 offsets into corner_v_
  int faces_with_uv_ = -1;         // -1: no face yet; else 0/1 of the first
};

int ObjParser::ResolveIndex(long long index, long long count, const char* what,
                            std::string_view token) {
  if (index > 0 && index <= count) return static_cast<int>(index - 1);
  if (index < 0 && -index <= count) return static_cast<int>(count + index);
  if (index == 0) {
    Fail("face corner '{}' has {} index 0 (OBJ indices start at 1)", token, what);
  }
  Fail("face corner '{}' refers to {} {} but only {} are defined before this "
       "line", token, what, index, count);
}

void ObjParser::ParseVertex(const char* p, const char* end) {
  // `v x y z [w]` or `v x y z r g b` (vertex colours): keep x y z.
  double xyz[3];
  int n = 0;
  for (std::string_view token = NextToken(p, end); !token.empty();
       token = NextToken(p, end), ++n) {
    double value = 0;
    if (!ParseDouble(token, &value)) {
      Fail("vertex has a malformed number '{}'", token);
    }
    if (!std::isfinite(value)) Fail("vertex has a non-finite number '{}'", token);
    if (n < 3) xyz[n] = value;
  }
  if (n < 3) Fail("vertex has {} coordinates, expected 3 (truncated line?)", n);
  if (n == 5 || n > 7) {
    Fail("vertex has {} numbers, expected x y z [w] or x y z r g b [a]", n);
  }
  for (double value : xyz) positions_.push_back(value * options_.scale);
}

void ObjParser::ParseTexCoord(const char* p, const char* end) {
  double uv[2];
  int n = 0;
  for (std::string_view token = NextToken(p, end); !token.empty();
       token = NextToken(p, end), ++n) {
    double value = 0;
    if (!ParseDouble(token, &value)) {
      Fail("texture coordinate has a malformed number '{}'", token);
    }
    if (!std::isfinite(value)) {
      Fail("texture coordinate has a non-finite number '{}'", token);
    }
    if (n < 2) uv[n] = value;
  }
  // A lone `vt u` is legal OBJ (1D texture) but no UV chart: refuse it.
  if (n < 2) Fail("texture coordinate has {} numbers, expected 2 (truncated line?)", n);
  if (n > 3) Fail("texture coordinate has {} numbers, expected 2 or 3", n);
  uvs_.push_back(uv[0]);
  uvs_.push_back(uv[1]);
}

// Parses the signed integer that starts at *p (stopping at '/' or the end
// of the token); false if there is none.
bool ReadIndexDigits(const char*& p, const char* end, long long* value) {
  bool negative = false;
  if (p < end && (*p == '-' || *p == '+')) negative = *p++ == '-';
  const char* start = p;
  long long v = 0;
  while (p < end && *p >= '0' && *p <= '9' && p - start < 15) {
    v = v * 10 + (*p++ - '0');
  }
  if (p == start) return false;
  *value = negative ? -v : v;
  return true;
}

void ObjParser::ParseFace(const char* p, const char* end) {
  const long long counts[3] = {static_cast<long long>(positions_.size() / 3),
                               static_cast<long long>(uvs_.size() / 2),
                               num_normals_};
  static const char* const kWhat[3] = {"vertex", "texture coordinate", "normal"};
  int corners = 0;
  int with_uv = 0;
  for (std::string_view token = NextToken(p, end); !token.empty();
       token = NextToken(p, end), ++corners) {
    // v, v/vt, v//vn or v/vt/vn; hand-parsed, this is the bulk of a file.
    const char* q = token.data();
    const char* const token_end = q + token.size();
    for (int part = 0; part < 3; ++part) {
      long long index = 0;
      const bool has_digits = ReadIndexDigits(q, token_end, &index);
      if (has_digits) {
        const int resolved = ResolveIndex(index, counts[part], kWhat[part], token);
        if (part == 0) corner_v_.push_back(resolved);
        if (part == 1) {
          corner_vt_.push_back(resolved);
          ++with_uv;
        }
      } else if (part != 1 || q == token_end || *q != '/') {
        // Only the texture index may be empty, as in "v//vn".
        Fail("face corner '{}' is malformed or cut off", token);
      }
      if (q == token_end) break;
      if (*q != '/' || part == 2) Fail("face corner '{}' is malformed", token);
      ++q;
      if (q == token_end) Fail("face corner '{}' is cut off after '/'", token);
    }
  }
  if (corners < 3) {
    Fail("face has {} corner(s), a polygon needs at least 3 (truncated line?)",
         corners);
  }
  if (with_uv != 0 && with_uv != corners) {
    Fail("face gives texture coordinates for {} of its {} corners", with_uv,
         corners);
  }
  const int has_uv = with_uv > 0 ? 1 : 0;
  if (faces_with_uv_ < 0) {
    faces_with_uv_ = has_uv;
  } else if (faces_with_uv_ != has_uv) {
    Fail(has_uv ? "face has texture coordinates but earlier faces have none"
                : "face has no texture coordinates but earlier faces have them");
  }
  polygon_begin_.push_back(static_cast<int>(corner_v_.size()));
}

TriMesh ObjParser::Parse(ObjPolygons* polygons) {
  polygon_begin_.push_back(0);
  const char* p = text_.data();
  const char* const end = p + text_.size();
  // A UTF-8 byte-order mark, as some Windows tools write.
  if (text_.size() >= 3 && std::memcmp(p, "\xEF\xBB\xBF", 3) == 0) p += 3;
  while (p < end) {
    ++line_;
    const char* line_end =
        static_cast<const char*>(std::memchr(p, '\n', static_cast<size_t>(end - p)));
    if (line_end == nullptr) line_end = end;
    const char* content_end = line_end;
    if (const void* hash = std::memchr(p, '#', static_cast<size_t>(line_end - p))) {
      content_end = static_cast<const char*>(hash);
    }
    const char* q = p;
    const std::string_view keyword = NextToken(q, content_end);
    if (keyword.empty()) {
      // Blank or comment line.
    } else if (keyword == "v") {
      ParseVertex(q, content_end);
    } else if (keyword == "vt") {
      ParseTexCoord(q, content_end);
    } else if (keyword == "f") {
      ParseFace(q, content_end);
    } else if (keyword == "vn") {
      ++num_normals_;  // Counted so face corners' normal indices are checked.
    } else if (keyword.back() == '\\') {
      Fail("line continuation ('\\') is not supported");
    } else if (!IsIgnoredStatement(keyword)) {
      Fail("unknown OBJ statement '{}' (truncated or not an OBJ file?)",
           keyword);
    }
    p = line_end + 1;
  }
  line_ = 0;
  const int num_vertices = static_cast<int>(positions_.size() / 3);
  if (num_vertices == 0) Fail("no vertices (empty or not an OBJ file)");
  const int num_polygons = static_cast<int>(polygon_begin_.size()) - 1;
  const bool has_uv = faces_with_uv_ == 1;
  if (options_.require_uvs && !has_uv) {
    Fail(num_polygons == 0 ? "no faces, hence no texture coordinates"
                           : "faces have no texture coordinates (vt), which "
                             "this file needs");
  }

  TriMesh mesh;
  mesh.V = Eigen::Map<const MatX3d>(positions_.data(), num_vertices, 3);
  int num_triangles = 0;
  for (int f = 0; f < num_polygons; ++f) {
    num_triangles += polygon_begin_[f + 1] - polygon_begin_[f] - 2;
  }
  mesh.F.resize(num_triangles, 3);
  if (has_uv) {
    mesh.UV = Eigen::Map<const MatX2d>(uvs_.data(),
                                       static_cast<int>(uvs_.size() / 2), 2);
    mesh.FUV.resize(num_triangles, 3);
  }
  if (polygons != nullptr) {
    polygons->first_triangle.resize(num_polygons);
    polygons->corners.resize(num_polygons);
  }
  int t = 0;
  for (int f = 0; f < num_polygons; ++f) {
    const int begin = polygon_begin_[f];
    const int corners = polygon_begin_[f + 1] - begin;
    if (polygons != nullptr) {
      polygons->first_triangle[f] = t;
      polygons->corners[f] = corners;
    }
    // Fan from the first corner: exact for the convex polygons DCCs export.
    for (int j = 1; j + 1 < corners; ++j, ++t) {
      mesh.F.row(t) << corner_v_[begin], corner_v_[begin + j],
          corner_v_[begin + j + 1];
      if (has_uv) {
        mesh.FUV.row(t) << corner_vt_[begin], corner_vt_[begin + j],
            corner_vt_[begin + j + 1];
      }
    }
  }
  return mesh;
}

void CheckPrecision(int precision, const std::filesystem::path& origin) {
  if (precision < 1 || precision > 17) {
    ThrowInputError(origin, 0,
                    "OBJ precision must be 1..17 significant digits, got {}",
                    precision);
  }
}

}  // namespace

TriMesh ParseObj(std::string_view text, const std::filesystem::path& origin,
                 const ObjReadOptions& options, ObjPolygons* polygons) {
  if (!(std::isfinite(options.scale) && options.scale > 0)) {
    ThrowInputError(origin, 0, "OBJ scale must be positive, got {}",
                    options.scale);
  }
  return ObjParser(text, origin, options).Parse(polygons);
}

TriMesh ReadObj(const std::filesystem::path& path,
                const ObjReadOptions& options) {
  const std::string text = ReadFile(path);
  return ParseObj(text, path, options);
}

namespace {

// Appends with std::to_chars into a buffer sized for the worst case: fmt's
// runtime-precision formatting was the bulk of writing an actor's shapes.
class TextWriter {
 public:
  explicit TextWriter(size_t capacity) : text_(capacity, '\0'), p_(text_.data()) {}

  void Literal(std::string_view s) {
    std::memcpy(p_, s.data(), s.size());
    p_ += s.size();
  }
  void Char(char c) { *p_++ = c; }
  void Number(double value, int precision) {
    p_ = std::to_chars(p_, text_.data() + text_.size(), value,
                       std::chars_format::general, precision)
             .ptr;
  }
  void Index(int value) {
    p_ = std::to_chars(p_, text_.data() + text_.size(), value).ptr;
  }
  std::string Finish() {
    text_.resize(static_cast<size_t>(p_ - text_.data()));
    return std::move(text_);
  }

 private:
  std::string text_;
  char* p_;
};

// Longest `%.17g` of a double ("-1.2345678901234567e-308") and of an int.
constexpr size_t kMaxNumber = 24;
constexpr size_t kMaxIndex = 11;

}  // namespace

std::string FormatObj(const TriMesh& topology, const MatX3d& V, int precision,
                      const std::filesystem::path& origin) {
  CheckPrecision(precision, origin);
  HMC_CHECK(V.rows() == topology.V.rows() || topology.V.rows() == 0);
  const bool has_uv = topology.HasUVs();
  HMC_CHECK(!has_uv || topology.FUV.rows() == topology.F.rows());
  HMC_CHECK(topology.F.size() == 0 ||
            (topology.F.minCoeff() >= 0 && topology.F.maxCoeff() < V.rows()));
  if (!V.allFinite()) {
    for (int v = 0; v < V.rows(); ++v) {
      if (!V.row(v).allFinite()) {
        ThrowInputError(origin, 0, "vertex {} has a non-finite coordinate", v);
      }
    }
  }
  if (has_uv && !topology.UV.allFinite()) {
    ThrowInputError(origin, 0, "a texture coordinate is not finite");
  }
  const std::string header = fmt::format(
      "# hmc OBJ: millimetres, head space (+x actor's left, +y up, +z "
      "forward)\n# {} vertices, {} texture coordinates, {} triangles\n",
      V.rows(), topology.UV.rows(), topology.F.rows());
  const size_t capacity = header.size() +
                          static_cast<size_t>(V.rows()) * (3 + 3 * (kMaxNumber + 1)) +
                          static_cast<size_t>(topology.UV.rows()) * (4 + 2 * (kMaxNumber + 1)) +
                          static_cast<size_t>(topology.F.rows()) * (3 + 3 * (2 * kMaxIndex + 2));
  TextWriter out(capacity);
  out.Literal(header);
  for (int v = 0; v < V.rows(); ++v) {
    out.Literal("v ");
    out.Number(V(v, 0), precision);
    out.Char(' ');
    out.Number(V(v, 1), precision);
    out.Char(' ');
    out.Number(V(v, 2), precision);
    out.Char('\n');
  }
  for (int t = 0; t < topology.UV.rows(); ++t) {
    out.Literal("vt ");
    out.Number(topology.UV(t, 0), precision);
    out.Char(' ');
    out.Number(topology.UV(t, 1), precision);
    out.Char('\n');
  }
  for (int f = 0; f < topology.F.rows(); ++f) {
    out.Char('f');
    for (int i = 0; i < 3; ++i) {
      out.Char(' ');
      out.Index(topology.F(f, i) + 1);
      if (has_uv) {
        out.Char('/');
        out.Index(topology.FUV(f, i) + 1);
      }
    }
    out.Char('\n');
  }
  return out.Finish();
}

void WriteObj(const std::filesystem::path& path, const TriMesh& topology,
              const MatX3d& V, int precision) {
  const std::string text = FormatObj(topology, V, precision, path);
  WriteFileAtomic(path, text);
}

void WriteObj(const std::filesystem::path& path, const TriMesh& mesh,
              int precision) {
  WriteObj(path, mesh, mesh.V, precision);
}

}  // namespace hmc
