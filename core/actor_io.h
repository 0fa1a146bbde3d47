// The actor package's readers and writer, split by file kind (internal to
// core/; the interface is core/actor.h): actor_text.cc (the hash and the
// text helpers the readers share), actor_yaml.cc (actor.yaml), actor_markers.cc
// (markers.csv), actor.cc (jaw weights, LoadActor, ValidateActor) and
// actor_write.cc (WriteActor). Formats: docs/formats.md, "Actor package".
#pragma once

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "core/actor.h"
#include "core/obj_io.h"
#include "core/text.h"

namespace hmc::actor_io {

namespace fs = std::filesystem;

constexpr char kYamlFile[] = "actor.yaml";
constexpr char kMarkersHeader[] = "name,vertex,face,weights,tags";
// Barycentric weights may be this far below 0 or their sum this far from 1:
// rounding in a DCC's or spreadsheet's export, not a marker off its face.
constexpr double kWeightTolerance = 1e-6;
// How far the jaw axes may be from orthonormal before they are refused
// (they are then snapped to the nearest rotation).
constexpr double kAxesTolerance = 1e-4;
// Largest |coordinate| of a neutral vertex, a shape displacement or the jaw
// pivot (mm): 100 m. A face is 0.2 m; beyond this a value is a typo or an
// overflow whose squares are no longer finite in the solve.
constexpr double kMaxCoordinateMm = 1e5;

// 64-bit FNV-1a (Fowler, Noll, Vo), applied to 8-byte words
// instead of bytes (8x fewer multiplies; the tail is hashed bytewise):
// simple, stable across platforms and runs, and fast next to parsing. Each
// file is hashed alone (in parallel with the others), then the per-file
// hashes are combined in the package's order. Not cryptographic: it only
// tells a cache that the package changed.
constexpr uint64_t kFnvOffset = 14695981039346656037ull;
constexpr uint64_t kFnvPrime = 1099511628211ull;

constexpr char kNameRule[] =
    "letters, digits, '_', '.', '-', starting with a letter, digit or '_'";

// The content hash of Actor::content_hash: Fnv1a of each file, combined in
// the package's order by CombineHash.
uint64_t Fnv1a(std::string_view bytes, uint64_t hash = kFnvOffset);
uint64_t CombineHash(uint64_t hash, const std::string& name, uint64_t file_hash);

// Names of markers, shapes and tags end up in file names (shapes), CSV
// columns and YAML keys downstream: keep them to a safe alphabet (kNameRule).
bool IsValidName(const std::string& name);

// Text helpers of the readers: core/text.h (Trim, SplitWhitespace,
// ParseDouble, ParseInteger, ForEachLine, SplitCsvRecord).

// actor.yaml as written (paths relative to the package, file units).
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

PackageEntry ParseActorYaml(const std::string& text, const fs::path& file);

// LoadActor without the process cache (actor.cc; the cache: actor_cache.cc).
Actor LoadActorPackage(const fs::path& dir);

// markers.csv against the neutral (its OBJ polygons resolve face indices).
std::vector<Marker> ParseMarkersCsv(std::string_view text, const fs::path& file,
                                    const TriMesh& mesh,
                                    const ObjPolygons& polygons,
                                    const fs::path& neutral_file);

}  // namespace hmc::actor_io
