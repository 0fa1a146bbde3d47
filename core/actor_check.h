// Plausibility warnings on a loaded, valid actor (`hmc actor check`;
// docs/formats.md, "Warnings of hmc actor check"): what LoadActor cannot
// refuse because it is legal, but is most likely a mistake of the export:
// the head far from head space's origin or not +y up / +z forward, units
// that make the head centimetres or metres big or small, marker tags hmc
// does not know (a misspelt `stabel`).
#pragma once

#include <string>
#include <vector>

#include "core/actor.h"

namespace hmc {

struct ActorWarning {
  std::string kind;     // "origin", "orientation", "units", "tag"
  std::string message;  // one line, names what it found and what to do
};

// The thresholds (mm, degrees) the warnings use.
constexpr double kHeadCentreMaxMm = 100.0;   // bbox centre from the origin
constexpr double kUpMaxDeg = 35.0;           // stable-to-jaw direction from +y
constexpr double kForwardMaxDeg = 60.0;      // markers' mean normal from +z
constexpr double kHeadSizeMinMm = 60.0;      // largest extent of the neutral
constexpr double kHeadSizeMaxMm = 600.0;

// The marker tags hmc reads (`stable`, `jaw`, `lower_lip`) and the region
// tags of docs/formats.md's examples and the synthetic actor.
const std::vector<std::string>& KnownMarkerTags();

// The tag of `known` with the smallest edit distance to `tag` (ties: the
// first).
std::string NearestTag(const std::string& tag, const std::vector<std::string>& known);

// The warnings, in the order origin, orientation, units, tag; empty for a
// plausible actor. A marker tag counts as known if it is in
// KnownMarkerTags() or on any of the actor's shapes (a region tag the
// package defines for itself).
std::vector<ActorWarning> ActorWarnings(const Actor& actor);

}  // namespace hmc
