#include "core/actor.h"

#include <charconv>
#include <cmath>
#include <cstring>
#include <exception>
#include <iterator>
#include <limits>
#include <map>
#include <set>
#include <string_view>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <yaml-cpp/yaml.h>

#include "core/error.h"
#include "core/file_util.h"
#include "core/logging.h"
#include "core/obj_io.h"
#include "core/parallel.h"
#include "core/triangle.h"

namespace hmc {

bool Marker::HasTag(const std::string& tag) const {
  for (const std::string& t : tags) {
    if (t == tag) return true;
  }
  return false;
}

int Actor::FindMarker(const std::string& marker_name) const {
  for (size_t i = 0; i < markers.size(); ++i) {
    if (markers[i].name == marker_name) return static_cast<int>(i);
  }
  return -1;
}

int Actor::FindShape(const std::string& shape_name) const {
  for (size_t i = 0; i < shapes.size(); ++i) {
    if (shapes[i].name == shape_name) return static_cast<int>(i);
  }
  return -1;
}

MatX3d Actor::ShapePositions(int n) const {
  HMC_CHECK(n >= 0 && n < static_cast<int>(shapes.size()));
  return neutral.V + shapes[n].displacement;
}

namespace {

namespace fs = std::filesystem;

constexpr char kYamlFile[] = "actor.yaml";
constexpr char kMarkersHeader[] = "name,vertex,face,weights,tags";
// Barycentric weights may be this far below 0 or their sum this far from 1:
// rounding in a DCC's or spreadsheet's export, not a marker off its face.
constexpr double kWeightTolerance = 1e-6;
// How far the jaw axes may be from orthonormal before they are refused
// (they are then snapped to the nearest rotation).
constexpr double kAxesTolerance = 1e-4;

// 64-bit FNV-1a (Fowler, Noll, Vo), applied to 8-byte words
// instead of bytes (8x fewer multiplies; the tail is hashed bytewise):
// simple, stable across platforms and runs, and fast next to parsing. Each
// file is hashed alone (in parallel with the others), then the per-file
// hashes are combined in the package's order. Not cryptographic: it only
// tells a cache that the package changed.
constexpr uint64_t kFnvOffset = 14695981039346656037ull;
constexpr uint64_t kFnvPrime = 1099511628211ull;

uint64_t Fnv1a(std::string_view bytes, uint64_t hash = kFnvOffset) {
  const auto* data = reinterpret_cast<const unsigned char*>(bytes.data());
  const size_t num_words = bytes.size() / 8;
  for (size_t w = 0; w < num_words; ++w) {
    uint64_t word;
    std::memcpy(&word, data + 8 * w, 8);  // Host order: x86 and ARM are LE.
    hash ^= word;
    hash *= kFnvPrime;
  }
  for (size_t i = 8 * num_words; i < bytes.size(); ++i) {
    hash ^= data[i];
    hash *= kFnvPrime;
  }
  hash ^= bytes.size();
  hash *= kFnvPrime;
  return hash;
}

uint64_t CombineHash(uint64_t hash, const std::string& name, uint64_t file_hash) {
  hash = Fnv1a(name, hash);
  hash = Fnv1a(std::string_view("\0", 1), hash);
  char bytes[8];
  for (int i = 0; i < 8; ++i) bytes[i] = static_cast<char>(file_hash >> (8 * i));
  return Fnv1a(std::string_view(bytes, 8), hash);
}

// Names of markers, shapes and tags end up in file names (shapes), CSV
// columns and YAML keys downstream: keep them to a safe alphabet.
bool IsValidName(const std::string& name) {
  if (name.empty()) return false;
  const auto ok_first = [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') ||
           (c >= '0' && c <= '9') || c == '_';
  };
  if (!ok_first(name[0])) return false;
  for (const char c : name) {
    if (!ok_first(c) && c != '.' && c != '-') return false;
  }
  return true;
}

constexpr char kNameRule[] =
    "letters, digits, '_', '.', '-', starting with a letter, digit or '_'";

std::string_view Trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t' ||
                        s.front() == '\r')) {
    s.remove_prefix(1);
  }
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' ||
                        s.back() == '\r')) {
    s.remove_suffix(1);
  }
  return s;
}

std::vector<std::string_view> SplitWhitespace(std::string_view s) {
  std::vector<std::string_view> parts;
  size_t i = 0;
  while (i < s.size()) {
    while (i < s.size() && (s[i] == ' ' || s[i] == '\t')) ++i;
    const size_t start = i;
    while (i < s.size() && s[i] != ' ' && s[i] != '\t') ++i;
    if (i > start) parts.push_back(s.substr(start, i - start));
  }
  return parts;
}

bool ParseNumber(std::string_view token, double* value) {
  const char* begin = token.data();
  const char* end = begin + token.size();
  if (begin < end && *begin == '+') ++begin;
  if (begin == end) return false;
  const auto [ptr, error] = std::from_chars(begin, end, *value);
  return error == std::errc() && ptr == end;
}

bool ParseInteger(std::string_view token, long long* value) {
  const char* begin = token.data();
  const char* end = begin + token.size();
  if (begin < end && *begin == '+') ++begin;
  if (begin == end) return false;
  const auto [ptr, error] = std::from_chars(begin, end, *value);
  return error == std::errc() && ptr == end;
}

// Lines of a text file with their 1-based numbers; strips a UTF-8 BOM and
// '\r'.
template <typename Body>
void ForEachLine(std::string_view text, const Body& body) {
  if (text.size() >= 3 && std::memcmp(text.data(), "\xEF\xBB\xBF", 3) == 0) {
    text.remove_prefix(3);
  }
  int line = 0;
  size_t pos = 0;
  while (pos < text.size()) {
    ++line;
    size_t end = text.find('\n', pos);
    if (end == std::string_view::npos) end = text.size();
    std::string_view content = text.substr(pos, end - pos);
    if (!content.empty() && content.back() == '\r') content.remove_suffix(1);
    body(line, content);
    pos = end + 1;
  }
}

// One CSV record (RFC 4180 quoting, as spreadsheets write it) of one line.
std::vector<std::string> SplitCsv(std::string_view line,
                                  const fs::path& file, int line_number) {
  std::vector<std::string> fields(1);
  bool quoted = false;
  for (size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (quoted) {
      if (c == '"' && i + 1 < line.size() && line[i + 1] == '"') {
        fields.back() += '"';
        ++i;
      } else if (c == '"') {
        quoted = false;
      } else {
        fields.back() += c;
      }
    } else if (c == '"') {
      quoted = true;
    } else if (c == ',') {
      fields.emplace_back();
    } else {
      fields.back() += c;
    }
  }
  if (quoted) ThrowInputError(file, line_number, "unterminated quoted field");
  for (std::string& field : fields) field = std::string(Trim(field));
  return fields;
}

// ---------------------------------------------------------------------------
// actor.yaml

int LineOf(const YAML::Node& node) {
  const YAML::Mark mark = node.Mark();
  return mark.line >= 0 ? mark.line + 1 : 0;
}

template <typename... Args>
[[noreturn]] void FailAt(const fs::path& file, const YAML::Node& node,
                         fmt::format_string<Args...> format, Args&&... args) {
  ThrowInputError(file, LineOf(node), format, std::forward<Args>(args)...);
}

// Checks that `node` is a mapping whose keys are all in `allowed`, each once.
void CheckKeys(const YAML::Node& node, const fs::path& file, const char* what,
               std::initializer_list<const char*> allowed) {
  if (!node.IsMap()) FailAt(file, node, "{} must be a mapping of keys", what);
  std::set<std::string> seen;
  for (const auto& item : node) {
    const std::string key = item.first.Scalar();
    bool known = false;
    for (const char* name : allowed) known = known || key == name;
    if (!known) {
      std::string list;
      for (const char* name : allowed) {
        list += list.empty() ? "" : ", ";
        list += name;
      }
      FailAt(file, item.first, "unknown key '{}' in {} (allowed: {})", key,
             what, list);
    }
    if (!seen.insert(key).second) {
      FailAt(file, item.first, "key '{}' appears twice in {}", key, what);
    }
  }
}

YAML::Node Require(const YAML::Node& map, const char* key, const fs::path& file,
                   const char* what) {
  const YAML::Node node = map[key];
  if (!node) FailAt(file, map, "{} lacks the required key '{}'", what, key);
  return node;
}

std::string GetString(const YAML::Node& node, const fs::path& file,
                      const char* what) {
  if (!node.IsScalar() || node.Scalar().empty()) {
    FailAt(file, node, "{} must be a non-empty string", what);
  }
  return node.Scalar();
}

double GetNumber(const YAML::Node& node, const fs::path& file,
                 const char* what) {
  double value = 0;
  if (!node.IsScalar() || !ParseNumber(Trim(node.Scalar()), &value)) {
    // yaml-cpp's as<double>() would also take ".nan" and ".inf"; the
    // package wants plain finite numbers only.
    FailAt(file, node, "{} must be a number, got '{}'", what,
           node.IsScalar() ? node.Scalar() : std::string("(not a scalar)"));
  }
  if (!std::isfinite(value)) {
    FailAt(file, node, "{} must be a finite number, got '{}'", what,
           node.Scalar());
  }
  return value;
}

Vec3 GetVec3(const YAML::Node& node, const fs::path& file, const char* what) {
  if (!node.IsSequence() || node.size() != 3) {
    FailAt(file, node, "{} must be a list of 3 numbers [x, y, z]", what);
  }
  Vec3 v;
  for (int i = 0; i < 3; ++i) v[i] = GetNumber(node[i], file, what);
  return v;
}

std::vector<std::string> GetTags(const YAML::Node& node, const fs::path& file,
                                 const char* what) {
  if (!node.IsSequence()) FailAt(file, node, "{} must be a list of tags", what);
  std::vector<std::string> tags;
  for (const auto& item : node) {
    const std::string tag = GetString(item, file, what);
    if (!IsValidName(tag)) {
      FailAt(file, item, "tag '{}' in {} is not a valid name ({})", tag, what,
             kNameRule);
    }
    tags.push_back(tag);
  }
  return tags;
}

struct ShapeEntry {
  std::string name;
  fs::path file;  // as written in actor.yaml, relative to the package
  JawPose jaw;
  std::vector<std::string> tags;
  int line = 0;
};

struct JawRigEntry {
  Vec3 pivot;  // file units
  Mat3 axes;
  fs::path weights;
  int line = 0;
};

struct PackageEntry {
  std::string name;
  std::string units;
  fs::path neutral;
  fs::path markers;
  std::vector<ShapeEntry> shapes;
  std::optional<JawRigEntry> jaw_rig;
};

PackageEntry ParseActorYaml(const std::string& text, const fs::path& file) {
  YAML::Node root_node;
  try {
    root_node = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    ThrowInputError(file, e.mark.line >= 0 ? e.mark.line + 1 : 0,
                    "not valid YAML: {}", e.msg);
  }
  const YAML::Node& root = root_node;
  if (!root.IsMap()) ThrowInputError(file, 0, "must be a YAML mapping of keys");
  CheckKeys(root, file, "actor.yaml",
            {"version", "name", "units", "neutral", "markers", "shapes",
             "jaw_rig"});
  if (const YAML::Node version = root["version"]) {
    if (GetNumber(version, file, "version") != 1) {
      FailAt(file, version, "unsupported package version '{}' (this hmc reads 1)",
             version.Scalar());
    }
  }
  PackageEntry entry;
  entry.name = GetString(Require(root, "name", file, "actor.yaml"), file, "name");
  const YAML::Node units = Require(root, "units", file, "actor.yaml");
  entry.units = GetString(units, file, "units");
  if (entry.units != "mm" && entry.units != "cm") {
    FailAt(file, units, "units must be 'mm' or 'cm', got '{}'", entry.units);
  }
  entry.neutral = GetString(Require(root, "neutral", file, "actor.yaml"), file,
                            "neutral");
  entry.markers = GetString(Require(root, "markers", file, "actor.yaml"), file,
                            "markers");

  if (const YAML::Node shapes = root["shapes"]) {
    if (!shapes.IsSequence() && !shapes.IsNull()) {
      FailAt(file, shapes, "shapes must be a list");
    }
    std::map<std::string, int> shape_lines;
    for (const auto& item : shapes) {
      CheckKeys(item, file, "a shape", {"name", "file", "jaw", "tags"});
      ShapeEntry shape;
      shape.line = LineOf(item);
      const YAML::Node name = Require(item, "name", file, "a shape");
      shape.name = GetString(name, file, "shape name");
      if (!IsValidName(shape.name)) {
        FailAt(file, name, "shape name '{}' is not a valid name ({})",
               shape.name, kNameRule);
      }
      const auto [it, inserted] = shape_lines.emplace(shape.name, shape.line);
      if (!inserted) {
        FailAt(file, name, "duplicate shape name '{}' (first on line {})",
               shape.name, it->second);
      }
      if (const YAML::Node shape_file = item["file"]) {
        shape.file = GetString(shape_file, file, "shape file");
      } else {
        shape.file = fs::path("shapes") / (shape.name + ".obj");
      }
      if (const YAML::Node jaw = item["jaw"]) {
        const auto& names = JawPose::ParameterNames();
        CheckKeys(jaw, file, "a shape's jaw pose",
                  {names[0].c_str(), names[1].c_str(), names[2].c_str()});
        std::array<double, 3> values = {0, 0, 0};
        for (int i = 0; i < 3; ++i) {
          if (const YAML::Node value = jaw[names[i]]) {
            values[i] = GetNumber(value, file, names[i].c_str());
          }
        }
        shape.jaw = JawPose::FromArray(values);
      }
      if (const YAML::Node tags = item["tags"]) {
        shape.tags = GetTags(tags, file, "shape tags");
      }
      entry.shapes.push_back(std::move(shape));
    }
  }

  if (const YAML::Node rig = root["jaw_rig"]) {
    CheckKeys(rig, file, "jaw_rig",
              {"pivot", "hinge", "vertical", "forward", "weights"});
    JawRigEntry jaw;
    jaw.line = LineOf(rig);
    jaw.pivot = GetVec3(Require(rig, "pivot", file, "jaw_rig"), file,
                        "jaw_rig pivot");
    const char* axis_names[3] = {"hinge", "vertical", "forward"};
    for (int i = 0; i < 3; ++i) {
      jaw.axes.col(i) = GetVec3(Require(rig, axis_names[i], file, "jaw_rig"),
                                file, axis_names[i]);
    }
    const Mat3 gram = jaw.axes.transpose() * jaw.axes;
    if ((gram - Mat3::Identity()).cwiseAbs().maxCoeff() > kAxesTolerance ||
        jaw.axes.determinant() <= 0) {
      FailAt(file, rig,
             "jaw_rig axes hinge, vertical, forward must be orthonormal and "
             "right-handed (hinge x vertical = forward)");
    }
    // Snap to the nearest rotation, so rounding in the file does not make
    // the jaw transform slightly non-rigid.
    Eigen::JacobiSVD<Mat3> svd(jaw.axes, Eigen::ComputeFullU | Eigen::ComputeFullV);
    jaw.axes = svd.matrixU() * svd.matrixV().transpose();
    jaw.weights = GetString(Require(rig, "weights", file, "jaw_rig"), file,
                            "jaw_rig weights");
    entry.jaw_rig = jaw;
  }
  for (const ShapeEntry& shape : entry.shapes) {
    if (!entry.jaw_rig && !shape.jaw.IsZero()) {
      ThrowInputError(file, shape.line,
                      "shape '{}' has a jaw pose but the package has no "
                      "jaw_rig",
                      shape.name);
    }
  }
  return entry;
}

// ---------------------------------------------------------------------------
// markers.csv

// First triangle using each vertex (-1: none), for vertex markers.
std::vector<int> FirstFaceOfVertex(const TriMesh& mesh) {
  std::vector<int> first(mesh.NumVertices(), -1);
  for (int f = mesh.NumFaces() - 1; f >= 0; --f) {
    for (int i = 0; i < 3; ++i) first[mesh.F(f, i)] = f;
  }
  return first;
}

SurfacePoint PointAtVertex(const TriMesh& mesh, const std::vector<int>& first,
                           int v) {
  SurfacePoint point;
  point.face = first[v];
  point.bary = Vec3::Zero();
  for (int i = 0; i < 3; ++i) {
    if (mesh.F(point.face, i) == v) {
      point.bary[i] = 1;
      break;
    }
  }
  return point;
}

// A marker on OBJ polygon `polygon` with one weight per polygon corner, as a
// point on the fanned triangles. Triangles: exact. Polygons: the weighted
// corner position is projected on the nearest fan triangle, which is exact
// for planar convex polygons (the point lies in one of the fan triangles).
SurfacePoint PointOnPolygon(const TriMesh& mesh, const ObjPolygons& polygons,
                            int polygon, const std::vector<double>& weights) {
  const int first = polygons.first_triangle[polygon];
  const int corners = polygons.corners[polygon];
  SurfacePoint point;
  if (corners == 3) {
    point.face = first;
    point.bary = Vec3(weights[0], weights[1], weights[2]);
    return point;
  }
  // Corner k of the polygon: corner 0 of its first triangle, then corner
  // 1 of triangle k - 1 (k >= 1), and corner 2 of the last triangle.
  const auto corner_vertex = [&](int k) {
    if (k == 0) return mesh.F(first, 0);
    if (k == corners - 1) return mesh.F(first + corners - 3, 2);
    return mesh.F(first + k - 1, 1);
  };
  Vec3 p = Vec3::Zero();
  for (int k = 0; k < corners; ++k) {
    p += weights[k] * mesh.V.row(corner_vertex(k)).transpose();
  }
  double best = std::numeric_limits<double>::infinity();
  for (int j = 0; j < corners - 2; ++j) {
    const int t = first + j;
    const Vec3 a = mesh.V.row(mesh.F(t, 0)), b = mesh.V.row(mesh.F(t, 1)),
               c = mesh.V.row(mesh.F(t, 2));
    const Vec3 bary = ClosestPointBarycentrics(p, a, b, c);
    const double distance = (bary[0] * a + bary[1] * b + bary[2] * c - p).norm();
    if (distance < best) {
      best = distance;
      point.face = t;
      point.bary = bary;
    }
  }
  return point;
}

std::vector<Marker> ParseMarkersCsv(std::string_view text, const fs::path& file,
                                    const TriMesh& mesh,
                                    const ObjPolygons& polygons,
                                    const fs::path& neutral_file) {
  std::vector<Marker> markers;
  const std::vector<int> first_face = FirstFaceOfVertex(mesh);
  std::map<std::string, int> name_lines;
  int columns[5] = {-1, -1, -1, -1, -1};  // name, vertex, face, weights, tags
  static const char* const kColumns[5] = {"name", "vertex", "face", "weights",
                                          "tags"};
  bool have_header = false;
  ForEachLine(text, [&](int line, std::string_view content) {
    const std::string_view trimmed = Trim(content);
    if (trimmed.empty() || trimmed[0] == '#') return;
    const std::vector<std::string> fields = SplitCsv(content, file, line);
    if (!have_header) {
      for (size_t i = 0; i < fields.size(); ++i) {
        int column = -1;
        for (int c = 0; c < 5; ++c) {
          if (fields[i] == kColumns[c]) column = c;
        }
        if (column < 0) {
          ThrowInputError(file, line,
                          "unknown column '{}' in the header (expected {})",
                          fields[i], kMarkersHeader);
        }
        if (columns[column] >= 0) {
          ThrowInputError(file, line, "column '{}' appears twice", fields[i]);
        }
        columns[column] = static_cast<int>(i);
      }
      for (int c = 0; c < 5; ++c) {
        if (columns[c] < 0) {
          ThrowInputError(file, line, "header lacks the column '{}' (expected {})",
                          kColumns[c], kMarkersHeader);
        }
      }
      have_header = true;
      return;
    }
    if (fields.size() != 5) {
      ThrowInputError(file, line, "row has {} fields, the header has 5",
                      fields.size());
    }
    Marker marker;
    marker.name = fields[columns[0]];
    if (!IsValidName(marker.name)) {
      ThrowInputError(file, line, "marker name '{}' is not a valid name ({})",
                      marker.name, kNameRule);
    }
    const auto [it, inserted] = name_lines.emplace(marker.name, line);
    if (!inserted) {
      ThrowInputError(file, line, "duplicate marker name '{}' (first on line {})",
                      marker.name, it->second);
    }
    const std::string& vertex_field = fields[columns[1]];
    const std::string& face_field = fields[columns[2]];
    const std::string& weights_field = fields[columns[3]];
    if (vertex_field.empty() == face_field.empty()) {
      ThrowInputError(file, line,
                      "marker '{}' must give either a vertex or a face (with "
                      "weights), not {}",
                      marker.name, vertex_field.empty() ? "neither" : "both");
    }
    if (!vertex_field.empty()) {
      long long v = 0;
      if (!ParseInteger(vertex_field, &v)) {
        ThrowInputError(file, line, "marker '{}': vertex '{}' is not an integer",
                        marker.name, vertex_field);
      }
      if (v < 0 || v >= mesh.NumVertices()) {
        ThrowInputError(file, line,
                        "marker '{}' is off the mesh: vertex {} is not in "
                        "0..{} ({} has {} vertices; indices start at 0)",
                        marker.name, v, mesh.NumVertices() - 1,
                        neutral_file.filename().string(), mesh.NumVertices());
      }
      if (first_face[v] < 0) {
        ThrowInputError(file, line,
                        "marker '{}' is off the mesh: vertex {} belongs to no "
                        "face of {}",
                        marker.name, v, neutral_file.filename().string());
      }
      if (!weights_field.empty()) {
        ThrowInputError(file, line,
                        "marker '{}' gives weights with a vertex; weights go "
                        "with a face",
                        marker.name);
      }
      marker.vertex = static_cast<int>(v);
      marker.point = PointAtVertex(mesh, first_face, marker.vertex);
    } else {
      long long f = 0;
      if (!ParseInteger(face_field, &f)) {
        ThrowInputError(file, line, "marker '{}': face '{}' is not an integer",
                        marker.name, face_field);
      }
      if (f < 0 || f >= polygons.NumPolygons()) {
        ThrowInputError(file, line,
                        "marker '{}' is off the mesh: face {} is not in 0..{} "
                        "({} has {} faces; indices start at 0)",
                        marker.name, f, polygons.NumPolygons() - 1,
                        neutral_file.filename().string(),
                        polygons.NumPolygons());
      }
      const int corners = polygons.corners[f];
      std::vector<double> weights;
      for (const std::string_view token : SplitWhitespace(weights_field)) {
        double w = 0;
        if (!ParseNumber(token, &w) || !std::isfinite(w)) {
          ThrowInputError(file, line,
                          "marker '{}': weight '{}' is not a finite number",
                          marker.name, token);
        }
        weights.push_back(w);
      }
      if (static_cast<int>(weights.size()) != corners) {
        ThrowInputError(file, line,
                        "marker '{}': face {} has {} corners but {} weights "
                        "are given (one per corner, space-separated)",
                        marker.name, f, corners, weights.size());
      }
      double sum = 0;
      for (const double w : weights) {
        if (w < -kWeightTolerance) {
          ThrowInputError(file, line,
                          "marker '{}' is off the mesh: weight {} on face {} "
                          "is negative",
                          marker.name, w, f);
        }
        sum += w;
      }
      if (std::abs(sum - 1) > kWeightTolerance) {
        ThrowInputError(file, line,
                        "marker '{}': weights on face {} sum to {}, not 1",
                        marker.name, f, sum);
      }
      for (double& w : weights) w = std::max(w, 0.0) / sum;
      marker.point = PointOnPolygon(mesh, polygons, static_cast<int>(f), weights);
    }
    for (const std::string_view tag : SplitWhitespace(fields[columns[4]])) {
      if (!IsValidName(std::string(tag))) {
        ThrowInputError(file, line, "marker '{}': tag '{}' is not a valid name ({})",
                        marker.name, tag, kNameRule);
      }
      marker.tags.emplace_back(tag);
    }
    markers.push_back(std::move(marker));
  });
  if (!have_header) {
    ThrowInputError(file, 0, "empty: expected the header '{}'", kMarkersHeader);
  }
  return markers;
}

// ---------------------------------------------------------------------------
// Jaw weights: one number in [0,1] per line, per neutral vertex in order.

Eigen::VectorXd ParseJawWeights(std::string_view text, const fs::path& file,
                                int num_vertices) {
  std::vector<double> weights;
  weights.reserve(num_vertices);
  ForEachLine(text, [&](int line, std::string_view content) {
    const std::string_view trimmed = Trim(content);
    if (trimmed.empty() || trimmed[0] == '#') return;
    double w = 0;
    if (!ParseNumber(trimmed, &w)) {
      ThrowInputError(file, line, "'{}' is not a number (one weight per line)",
                      trimmed);
    }
    if (!(w >= 0 && w <= 1)) {
      ThrowInputError(file, line, "jaw weight {} is outside [0, 1]", trimmed);
    }
    weights.push_back(w);
  });
  if (static_cast<int>(weights.size()) != num_vertices) {
    ThrowInputError(file, 0,
                    "has {} weights, the neutral has {} vertices (one weight "
                    "per vertex, in the neutral's order)",
                    weights.size(), num_vertices);
  }
  return Eigen::Map<const Eigen::VectorXd>(weights.data(), num_vertices);
}

std::string ReadPackageFile(const fs::path& path, const fs::path& yaml_file,
                            const std::string& what) {
  if (!fs::is_regular_file(path)) {
    ThrowInputError(path, 0, "missing: {} listed in {}", what,
                    yaml_file.string());
  }
  return ReadFile(path);
}

}  // namespace

Actor LoadActor(const fs::path& dir) {
  StageTimer timer("load actor " + dir.string());
  if (!fs::is_directory(dir)) {
    ThrowInputError(dir, 0, "actor package folder does not exist");
  }
  const fs::path yaml_file = dir / kYamlFile;
  if (!fs::is_regular_file(yaml_file)) {
    ThrowInputError(yaml_file, 0, "missing: not an actor package");
  }
  const std::string yaml_text = ReadFile(yaml_file);
  const PackageEntry entry = ParseActorYaml(yaml_text, yaml_file);
  const double scale = entry.units == "cm" ? 10.0 : 1.0;

  Actor actor;
  actor.name = entry.name;
  actor.units = entry.units;
  actor.dir = dir;
  uint64_t hash = CombineHash(kFnvOffset, kYamlFile, Fnv1a(yaml_text));

  const fs::path neutral_file = dir / entry.neutral;
  ObjPolygons polygons;
  {
    const std::string text =
        ReadPackageFile(neutral_file, yaml_file, "the neutral mesh");
    ObjReadOptions options;
    options.require_uvs = true;
    options.scale = scale;
    actor.neutral = ParseObj(text, neutral_file, options, &polygons);
    if (actor.neutral.NumFaces() == 0) {
      ThrowInputError(neutral_file, 0, "the neutral mesh has no faces");
    }
    hash = CombineHash(hash, entry.neutral.generic_string(), Fnv1a(text));
  }

  const fs::path markers_file = dir / entry.markers;
  {
    const std::string text =
        ReadPackageFile(markers_file, yaml_file, "the markers file");
    actor.markers = ParseMarkersCsv(text, markers_file, actor.neutral,
                                    polygons, neutral_file);
    hash = CombineHash(hash, entry.markers.generic_string(), Fnv1a(text));
  }

  if (entry.jaw_rig) {
    const fs::path weights_file = dir / entry.jaw_rig->weights;
    const std::string text =
        ReadPackageFile(weights_file, yaml_file, "the jaw weights file");
    JawRig rig;
    rig.pivot = entry.jaw_rig->pivot * scale;
    rig.axes = entry.jaw_rig->axes;
    rig.weights = ParseJawWeights(text, weights_file, actor.NumVertices());
    actor.jaw_rig = rig;
    hash = CombineHash(hash, entry.jaw_rig->weights.generic_string(),
                       Fnv1a(text));
  }

  // Shapes in parallel; each writes its own slot, and the first failure in
  // package order is reported, whatever the schedule.
  const int num_shapes = static_cast<int>(entry.shapes.size());
  actor.shapes.resize(num_shapes);
  std::vector<uint64_t> shape_hashes(num_shapes, 0);
  std::vector<std::exception_ptr> errors(num_shapes);
  Progress progress("load shapes", num_shapes, "shapes");
  ParallelFor(0, num_shapes, [&](int64_t n) {
    try {
      const ShapeEntry& shape_entry = entry.shapes[n];
      const fs::path shape_file = dir / shape_entry.file;
      const std::string text = ReadPackageFile(
          shape_file, yaml_file, "the OBJ of shape '" + shape_entry.name + "'");
      shape_hashes[n] = Fnv1a(text);
      ObjReadOptions options;
      options.scale = scale;
      const TriMesh mesh = ParseObj(text, shape_file, options);
      if (mesh.NumVertices() != actor.NumVertices()) {
        ThrowInputError(shape_file, 0,
                        "has {} vertices, the neutral {} has {} (a shape must "
                        "have the neutral's vertices in the same order)",
                        mesh.NumVertices(), entry.neutral.string(),
                        actor.NumVertices());
      }
      Shape& shape = actor.shapes[n];
      shape.name = shape_entry.name;
      shape.jaw = shape_entry.jaw;
      shape.tags = shape_entry.tags;
      shape.displacement = mesh.V - actor.neutral.V;
    } catch (...) {
      errors[n] = std::current_exception();
    }
    progress.Advance();
  });
  progress.Finish();
  for (int n = 0; n < num_shapes; ++n) {
    if (errors[n]) std::rethrow_exception(errors[n]);
    hash = CombineHash(hash, entry.shapes[n].file.generic_string(),
                       shape_hashes[n]);
  }
  actor.content_hash = hash;
  ValidateActor(actor, dir);
  spdlog::info("actor '{}': {} vertices, {} shapes, {} markers{}", actor.name,
               actor.NumVertices(), actor.shapes.size(), actor.markers.size(),
               actor.jaw_rig ? ", jaw rig" : "");
  return actor;
}

void ValidateActor(const Actor& actor, const fs::path& origin) {
  if (actor.name.empty()) ThrowInputError(origin, 0, "the actor has no name");
  if (actor.units != "mm" && actor.units != "cm") {
    ThrowInputError(origin, 0, "units must be 'mm' or 'cm', got '{}'", actor.units);
  }
  const TriMesh& mesh = actor.neutral;
  const int num_vertices = mesh.NumVertices();
  if (num_vertices == 0 || mesh.NumFaces() == 0) {
    ThrowInputError(origin, 0, "the neutral mesh is empty ({} vertices, {} faces)", num_vertices,
         mesh.NumFaces());
  }
  if (!mesh.V.allFinite()) ThrowInputError(origin, 0, "the neutral has a non-finite vertex position");
  if (mesh.F.minCoeff() < 0 || mesh.F.maxCoeff() >= num_vertices) {
    ThrowInputError(origin, 0, "a neutral triangle refers to a vertex outside 0..{}", num_vertices - 1);
  }
  if (!mesh.HasUVs()) ThrowInputError(origin, 0, "the neutral mesh has no UVs");
  if (mesh.FUV.rows() != mesh.NumFaces() || mesh.FUV.minCoeff() < 0 ||
      mesh.FUV.maxCoeff() >= mesh.UV.rows()) {
    ThrowInputError(origin, 0, "the neutral's UV corners (FUV) do not match its triangles and UVs");
  }
  if (!mesh.UV.allFinite()) ThrowInputError(origin, 0, "the neutral has a non-finite UV");

  std::set<std::string> names;
  for (const Shape& shape : actor.shapes) {
    if (!IsValidName(shape.name)) {
      ThrowInputError(origin, 0, "shape name '{}' is not a valid name ({})", shape.name, kNameRule);
    }
    if (!names.insert(shape.name).second) {
      ThrowInputError(origin, 0, "duplicate shape name '{}'", shape.name);
    }
    if (shape.displacement.rows() != num_vertices) {
      ThrowInputError(origin, 0, "shape '{}' has {} displacements, the neutral has {} vertices",
           shape.name, shape.displacement.rows(), num_vertices);
    }
    if (!shape.displacement.allFinite()) {
      ThrowInputError(origin, 0, "shape '{}' has a non-finite displacement", shape.name);
    }
    const auto jaw = shape.jaw.ToArray();
    for (const double value : jaw) {
      if (!std::isfinite(value)) ThrowInputError(origin, 0, "shape '{}' has a non-finite jaw pose", shape.name);
    }
    if (!actor.jaw_rig && !shape.jaw.IsZero()) {
      ThrowInputError(origin, 0, "shape '{}' has a jaw pose but the actor has no jaw rig", shape.name);
    }
    for (const std::string& tag : shape.tags) {
      if (!IsValidName(tag)) {
        ThrowInputError(origin, 0, "shape '{}': tag '{}' is not a valid name ({})", shape.name, tag,
             kNameRule);
      }
    }
  }

  names.clear();
  for (const Marker& marker : actor.markers) {
    if (!IsValidName(marker.name)) {
      ThrowInputError(origin, 0, "marker name '{}' is not a valid name ({})", marker.name, kNameRule);
    }
    if (!names.insert(marker.name).second) {
      ThrowInputError(origin, 0, "duplicate marker name '{}'", marker.name);
    }
    const SurfacePoint& point = marker.point;
    if (point.face < 0 || point.face >= mesh.NumFaces()) {
      ThrowInputError(origin, 0, "marker '{}' is off the mesh: triangle {} is not in 0..{}",
           marker.name, point.face, mesh.NumFaces() - 1);
    }
    if (!point.bary.allFinite() || point.bary.minCoeff() < -kWeightTolerance ||
        std::abs(point.bary.sum() - 1) > kWeightTolerance) {
      ThrowInputError(origin, 0, "marker '{}' is off the mesh: barycentric weights ({}, {}, {}) "
           "must be >= 0 and sum to 1",
           marker.name, point.bary[0], point.bary[1], point.bary[2]);
    }
    if (marker.vertex >= num_vertices) {
      ThrowInputError(origin, 0, "marker '{}' is off the mesh: vertex {} is not in 0..{}",
           marker.name, marker.vertex, num_vertices - 1);
    }
    if (marker.vertex >= 0) {
      int corner = 0;
      point.bary.maxCoeff(&corner);
      if (mesh.F(point.face, corner) != marker.vertex ||
          std::abs(point.bary[corner] - 1) > kWeightTolerance) {
        ThrowInputError(origin, 0, "marker '{}': its surface point is not at its vertex {}",
             marker.name, marker.vertex);
      }
    }
    for (const std::string& tag : marker.tags) {
      if (!IsValidName(tag)) {
        ThrowInputError(origin, 0, "marker '{}': tag '{}' is not a valid name ({})", marker.name,
             tag, kNameRule);
      }
    }
  }

  if (actor.jaw_rig) {
    const JawRig& rig = *actor.jaw_rig;
    if (!rig.pivot.allFinite()) ThrowInputError(origin, 0, "the jaw rig pivot is not finite");
    const Mat3 gram = rig.axes.transpose() * rig.axes;
    if (!rig.axes.allFinite() ||
        (gram - Mat3::Identity()).cwiseAbs().maxCoeff() > kAxesTolerance ||
        rig.axes.determinant() <= 0) {
      ThrowInputError(origin, 0, "the jaw rig axes are not orthonormal and right-handed");
    }
    if (rig.weights.size() != num_vertices) {
      ThrowInputError(origin, 0, "the jaw rig has {} weights, the neutral has {} vertices",
           rig.weights.size(), num_vertices);
    }
    for (int v = 0; v < num_vertices; ++v) {
      if (!(rig.weights[v] >= 0 && rig.weights[v] <= 1)) {
        ThrowInputError(origin, 0, "jaw weight of vertex {} is {}, outside [0, 1]", v, rig.weights[v]);
      }
    }
  }
}

namespace {

// A YAML double-quoted scalar: JSON string syntax is a subset of it.
std::string QuoteYaml(const std::string& text) {
  return nlohmann::json(text).dump();
}

std::string FormatVec3(const Vec3& v) {
  // "{}" is the shortest text that reads back to the same double.
  return fmt::format("[{}, {}, {}]", v[0], v[1], v[2]);
}

std::string FormatTags(const std::vector<std::string>& tags) {
  return fmt::format("[{}]", fmt::join(tags, ", "));
}

}  // namespace

void WriteActor(const Actor& actor, const fs::path& dir, int precision) {
  ValidateActor(actor, dir);
  if (precision < 1 || precision > 17) {
    ThrowInputError(dir, 0, "precision must be 1..17 significant digits, got {}",
                    precision);
  }
  StageTimer timer("write actor " + dir.string());
  EnsureDirectory(dir);
  if (!actor.shapes.empty()) EnsureDirectory(dir / "shapes");

  WriteObj(dir / "neutral.obj", actor.neutral, precision);

  fmt::memory_buffer markers;
  auto out = std::back_inserter(markers);
  fmt::format_to(out,
                 "# vertex and face: 0-based indices of the v and f lines of "
                 "neutral.obj\n{}\n",
                 kMarkersHeader);
  for (const Marker& marker : actor.markers) {
    const std::string tags = fmt::format("{}", fmt::join(marker.tags, " "));
    if (marker.vertex >= 0) {
      fmt::format_to(out, "{},{},,,{}\n", marker.name, marker.vertex, tags);
    } else {
      // neutral.obj is written as triangles, so OBJ face = triangle.
      fmt::format_to(out, "{},,{},{} {} {},{}\n", marker.name,
                     marker.point.face, marker.point.bary[0],
                     marker.point.bary[1], marker.point.bary[2], tags);
    }
  }
  WriteFileAtomic(dir / "markers.csv", fmt::to_string(markers));

  if (actor.jaw_rig) {
    fmt::memory_buffer weights;
    auto wout = std::back_inserter(weights);
    for (int v = 0; v < actor.jaw_rig->weights.size(); ++v) {
      fmt::format_to(wout, "{}\n", actor.jaw_rig->weights[v]);
    }
    WriteFileAtomic(dir / "jaw_weights.txt", fmt::to_string(weights));
  }

  const int num_shapes = static_cast<int>(actor.shapes.size());
  std::vector<std::exception_ptr> errors(num_shapes);
  Progress progress("write shapes", num_shapes, "shapes");
  ParallelFor(0, num_shapes, [&](int64_t n) {
    try {
      const Shape& shape = actor.shapes[n];
      WriteObj(dir / "shapes" / (shape.name + ".obj"), actor.neutral,
               actor.neutral.V + shape.displacement, precision);
    } catch (...) {
      errors[n] = std::current_exception();
    }
    progress.Advance();
  });
  progress.Finish();
  for (const std::exception_ptr& error : errors) {
    if (error) std::rethrow_exception(error);
  }

  // actor.yaml last: a package is complete once it exists.
  fmt::memory_buffer yaml;
  auto yout = std::back_inserter(yaml);
  fmt::format_to(yout,
                 "# hmc actor package (docs/formats.md, \"Actor package\").\n"
                 "version: 1\nname: {}\nunits: mm\nneutral: neutral.obj\n"
                 "markers: markers.csv\n",
                 QuoteYaml(actor.name));
  if (actor.jaw_rig) {
    const JawRig& rig = *actor.jaw_rig;
    fmt::format_to(yout,
                   "jaw_rig:\n  pivot: {}\n  hinge: {}\n  vertical: {}\n"
                   "  forward: {}\n  weights: jaw_weights.txt\n",
                   FormatVec3(rig.pivot), FormatVec3(rig.axes.col(0)),
                   FormatVec3(rig.axes.col(1)), FormatVec3(rig.axes.col(2)));
  }
  fmt::format_to(yout, "shapes:{}\n", actor.shapes.empty() ? " []" : "");
  const auto& jaw_names = JawPose::ParameterNames();
  for (const Shape& shape : actor.shapes) {
    fmt::format_to(yout, "  - name: {}\n    file: shapes/{}.obj\n", shape.name,
                   shape.name);
    if (actor.jaw_rig) {
      fmt::format_to(yout, "    jaw: {{{}: {}, {}: {}, {}: {}}}\n",
                     jaw_names[0], shape.jaw.open_deg, jaw_names[1],
                     shape.jaw.lateral_deg, jaw_names[2],
                     shape.jaw.protrude_mm);
    }
    if (!shape.tags.empty()) {
      fmt::format_to(yout, "    tags: {}\n", FormatTags(shape.tags));
    }
  }
  WriteFileAtomic(dir / kYamlFile, fmt::to_string(yaml));
}

}  // namespace hmc
