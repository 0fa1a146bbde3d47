// The day's markers (docs/registration.md): where the make-up artist really
// painted each dot on a shoot day, in markers.csv's format (docs/formats.md),
// replacing the actor package's marker points for every stage of that day
// (`--markers DAY_MARKERS`, registered once as DayMarkersOptions).
#pragma once

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "core/actor.h"
#include "core/obj_io.h"
#include "core/options.h"

namespace hmc {

// The one declaration of the `markers` option every stage that loads an
// actor shares (track, triangulate, stabilize, jaw, solve, report, run).
struct DayMarkersOptions {
  std::string markers;  // the day's markers (markers.csv format; "" = the package's own)

  void Register(OptionFields* fields);
  bool Check() const { return true; }
};

// markers.csv's text for `markers` (faces are triangles of the loaded
// neutral; with `polygons`, the OBJ polygons they were fanned from, whose
// corner weights are written, so the file reads back against the OBJ).
std::string FormatMarkersCsv(const std::vector<Marker>& markers,
                             const ObjPolygons* polygons = nullptr,
                             const std::string& comment = "");

// The OBJ polygons of the package's neutral (actor.dir's actor.yaml).
ObjPolygons NeutralPolygons(const Actor& actor);

// `actor` with its markers replaced by those of `markers_file` (read
// against the package's neutral as markers.csv is); content_hash combines
// the package's with the file's, so every cache keyed by it (the solve's
// index) is per marker set. Throws InputError naming the file.
Actor WithDayMarkers(const Actor& actor, const std::filesystem::path& markers_file);

// LoadActorShared(dir), with the day's markers when `markers_file` is set.
std::shared_ptr<const Actor> LoadActorForDay(const std::filesystem::path& dir,
                                             const std::string& markers_file);

}  // namespace hmc
