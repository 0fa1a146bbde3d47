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
#include "core/actor_io.h"

namespace hmc {

using namespace actor_io;  // NOLINT(build/namespaces): this module's helpers

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
    if (!ParseDouble(trimmed, &w)) {
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

Actor actor_io::LoadActorPackage(const fs::path& dir) {
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
  // Magnitudes the solve can square and sum (docs/reliability.md).
  auto require_sane = [&](const MatX3d& m, const std::string& what) {
    Eigen::Index row = 0, col = 0;
    if (m.rows() > 0 && m.cwiseAbs().maxCoeff(&row, &col) > kMaxCoordinateMm) {
      ThrowInputError(origin, 0, "{} of vertex {} is {} mm: beyond the sane bound of {} mm", what,
                      row, m(row, col), kMaxCoordinateMm);
    }
  };
  require_sane(mesh.V, "the neutral position");
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
    require_sane(shape.displacement, "shape '" + shape.name + "': the displacement");
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

  if (actor.markers.empty()) {
    ThrowInputError(origin, 0, "the actor has no markers (a solve needs at least one)");
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
    if (!rig.pivot.allFinite() || rig.pivot.cwiseAbs().maxCoeff() > kMaxCoordinateMm) {
      ThrowInputError(origin, 0, "the jaw rig pivot is not finite or beyond {} mm", kMaxCoordinateMm);
    }
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

}  // namespace hmc
