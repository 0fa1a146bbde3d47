#include "core/actor_io.h"

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

namespace hmc::actor_io {

namespace {

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
  return ClosestSurfacePoint(mesh, p, first, first + corners - 2);
}

// A marker's vertex or face index (`what`: "vertex" or "face", `what_plural`
// its plural): an integer in 0..count-1, else an input error naming the
// marker, the line and the neutral mesh.
int ParseMarkerIndex(std::string_view field, const char* what,
                     const char* what_plural, int count,
                     const std::string& marker_name, const fs::path& file,
                     int line, const fs::path& neutral_file) {
  long long index = 0;
  if (!ParseInteger(field, &index)) {
    ThrowInputError(file, line, "marker '{}': {} '{}' is not an integer",
                    marker_name, what, field);
  }
  if (index < 0 || index >= count) {
    ThrowInputError(file, line,
                    "marker '{}' is off the mesh: {} {} is not in 0..{} ({} "
                    "has {} {}; indices start at 0)",
                    marker_name, what, index, count - 1,
                    neutral_file.filename().string(), count, what_plural);
  }
  return static_cast<int>(index);
}

}  // namespace

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
    const std::vector<std::string> fields = SplitCsvRecord(content, file, line);
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
      const int v = ParseMarkerIndex(vertex_field, "vertex", "vertices",
                                     mesh.NumVertices(), marker.name, file,
                                     line, neutral_file);
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
      marker.vertex = v;
      marker.point = PointAtVertex(mesh, first_face, marker.vertex);
    } else {
      const int f = ParseMarkerIndex(face_field, "face", "faces",
                                     polygons.NumPolygons(), marker.name, file,
                                     line, neutral_file);
      const int corners = polygons.corners[f];
      std::vector<double> weights;
      for (const std::string_view token : SplitWhitespace(weights_field)) {
        double w = 0;
        if (!ParseDouble(token, &w) || !std::isfinite(w)) {
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
      marker.point = PointOnPolygon(mesh, polygons, f, weights);
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
  if (markers.empty()) {
    ThrowInputError(file, 0, "no markers after the header (a solve needs at least one)");
  }
  return markers;
}

}  // namespace hmc::actor_io
