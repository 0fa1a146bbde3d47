#include "core/day_markers.h"

#include <fmt/format.h>

#include "core/actor_cache.h"
#include "core/actor_io.h"
#include "core/error.h"
#include "core/file_util.h"

namespace hmc {

namespace fs = std::filesystem;

void DayMarkersOptions::Register(OptionFields* fields) {
  fields->Add("markers", &markers,
              "the day's markers (markers.csv format, from `hmc register`) replacing the actor "
              "package's marker points (\"\" = the package's own)");
}

std::string FormatMarkersCsv(const std::vector<Marker>& markers, const ObjPolygons* polygons,
                             const std::string& comment) {
  std::vector<int> polygon_of;  // triangle -> polygon
  if (polygons) {
    for (int p = 0; p < polygons->NumPolygons(); ++p) {
      for (int j = 0; j < polygons->corners[p] - 2; ++j) {
        const size_t t = static_cast<size_t>(polygons->first_triangle[p] + j);
        if (polygon_of.size() <= t) polygon_of.resize(t + 1, -1);
        polygon_of[t] = p;
      }
    }
  }
  std::string out = comment;
  out += "# vertex and face: 0-based indices of the v and f lines of neutral.obj\n";
  out += actor_io::kMarkersHeader;
  out += "\n";
  for (const Marker& marker : markers) {
    const std::string tags = fmt::format("{}", fmt::join(marker.tags, " "));
    if (marker.vertex >= 0) {
      out += fmt::format("{},{},,,{}\n", marker.name, marker.vertex, tags);
      continue;
    }
    const int t = marker.point.face;
    const int p = polygons && t < static_cast<int>(polygon_of.size()) ? polygon_of[t] : -1;
    if (p < 0 || polygons->corners[p] == 3) {
      out += fmt::format("{},,{},{} {} {},{}\n", marker.name, p < 0 ? t : p,
                         marker.point.bary[0], marker.point.bary[1], marker.point.bary[2],
                         tags);
      continue;
    }
    // Triangle j of a fanned polygon has corners 0, j + 1, j + 2.
    const int j = t - polygons->first_triangle[p];
    std::vector<double> w(polygons->corners[p], 0.0);
    w[0] = marker.point.bary[0];
    w[j + 1] = marker.point.bary[1];
    w[j + 2] = marker.point.bary[2];
    out += fmt::format("{},,{},{},{}\n", marker.name, p, fmt::join(w, " "), tags);
  }
  return out;
}

ObjPolygons NeutralPolygons(const Actor& actor) {
  const fs::path yaml_file = actor.dir / actor_io::kYamlFile;
  const actor_io::PackageEntry entry = actor_io::ParseActorYaml(ReadFile(yaml_file), yaml_file);
  const fs::path neutral_file = actor.dir / entry.neutral;
  ObjPolygons polygons;
  ObjReadOptions options;
  options.require_uvs = true;
  ParseObj(ReadFile(neutral_file), neutral_file, options, &polygons);
  return polygons;
}

Actor WithDayMarkers(const Actor& actor, const fs::path& markers_file) {
  if (!fs::is_regular_file(markers_file)) {
    ThrowInputError(markers_file, 0, "missing: the day's markers file (--markers)");
  }
  const fs::path yaml_file = actor.dir / actor_io::kYamlFile;
  const actor_io::PackageEntry entry = actor_io::ParseActorYaml(ReadFile(yaml_file), yaml_file);
  const ObjPolygons polygons = NeutralPolygons(actor);
  const std::string text = ReadFile(markers_file);
  Actor day = actor;
  day.markers = actor_io::ParseMarkersCsv(text, markers_file, actor.neutral, polygons,
                                          actor.dir / entry.neutral);
  if (day.markers.empty()) ThrowInputError(markers_file, 0, "lists no markers");
  day.content_hash = actor_io::CombineHash(actor.content_hash, "day_markers",
                                           actor_io::Fnv1a(text));
  ValidateActor(day, markers_file);
  return day;
}

std::shared_ptr<const Actor> LoadActorForDay(const fs::path& dir,
                                             const std::string& markers_file) {
  std::shared_ptr<const Actor> actor = LoadActorShared(dir);
  if (markers_file.empty()) return actor;
  return std::make_shared<const Actor>(WithDayMarkers(*actor, markers_file));
}

}  // namespace hmc
