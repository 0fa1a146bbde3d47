// The actor package (docs/formats.md): a folder a studio can assemble
// from OBJs, loaded into millimetres in head space. Format: docs/formats.md.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "core/jaw.h"
#include "core/mesh.h"

namespace hmc {

struct Marker {
  std::string name;
  SurfacePoint point;          // where the painted dot sits on the neutral
  int vertex = -1;             // the vertex when given by vertex, else -1
  std::vector<std::string> tags;  // "stable", "jaw", region tags ("mouth", ...)

  bool HasTag(const std::string& tag) const;
};

struct Shape {
  std::string name;
  MatX3d displacement;   // V x 3: b_n = shape_n - neutral (mm)
  JawPose jaw;           // the shape's jaw pose (zero without a jaw rig)
  std::vector<std::string> tags;  // optional region tags ("mouth", "brow")
};

struct Actor {
  std::string name;
  std::string units = "mm";  // units of the files on disk; loaded data is mm
  TriMesh neutral;           // with UVs
  std::vector<Shape> shapes;
  std::vector<Marker> markers;
  std::optional<JawRig> jaw_rig;

  // Set by LoadActor: the folder, and a hash of the contents of every file
  // the package consists of (caches built from the actor store it and are
  // rebuilt when it changes).
  std::filesystem::path dir;
  uint64_t content_hash = 0;

  int NumVertices() const { return neutral.NumVertices(); }
  int FindMarker(const std::string& name) const;  // -1 if absent
  int FindShape(const std::string& name) const;   // -1 if absent
  // Positions of shape n: neutral.V + shapes[n].displacement.
  MatX3d ShapePositions(int n) const;
};

// Loads and validates a package. Throws InputError naming the file, the line
// where it applies and what is wrong. Nothing is written.
Actor LoadActor(const std::filesystem::path& dir);

// Validates an in-memory actor (the checks LoadActor applies after parsing);
// throws InputError naming `origin` on the first problem.
void ValidateActor(const Actor& actor, const std::filesystem::path& origin);

// Writes a package to `dir` (created if missing) in millimetres; each file is
// written atomically. `precision`: significant digits of OBJ coordinates.
void WriteActor(const Actor& actor, const std::filesystem::path& dir,
                int precision = 9);

}  // namespace hmc
