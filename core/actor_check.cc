#include "core/actor_check.h"

#include <algorithm>
#include <cmath>
#include <map>

#include <fmt/format.h>

#include "core/text.h"

namespace hmc {
namespace {

double AngleBetweenDeg(const Vec3& a, const Vec3& b) {
  const double c = a.normalized().dot(b.normalized());
  return std::acos(std::clamp(c, -1.0, 1.0)) * 180.0 / M_PI;
}

// "+x", "-z", ...: the head-space axis nearest to `v`.
std::string NearestAxis(const Vec3& v) {
  int axis = 0;
  v.cwiseAbs().maxCoeff(&axis);
  return fmt::format("{}{}", v[axis] >= 0 ? '+' : '-', "xyz"[axis]);
}

// Mean position of the markers with any of `tags`; false if none.
bool MeanOfTagged(const Actor& actor, const std::vector<std::string>& tags, Vec3* mean) {
  Vec3 sum = Vec3::Zero();
  int n = 0;
  for (const Marker& marker : actor.markers) {
    if (std::none_of(tags.begin(), tags.end(),
                     [&](const std::string& t) { return marker.HasTag(t); })) {
      continue;
    }
    sum += EvaluateSurfacePoint(marker.point, actor.neutral.F, actor.neutral.V);
    ++n;
  }
  if (n == 0) return false;
  *mean = sum / n;
  return true;
}

void CheckOrigin(const Actor& actor, std::vector<ActorWarning>* out) {
  const Eigen::Matrix<double, 2, 3> box = BoundingBox(actor.neutral.V);
  const Vec3 centre = 0.5 * (box.row(0) + box.row(1)).transpose();
  if (centre.norm() <= kHeadCentreMaxMm) return;
  out->push_back({"origin", fmt::format(
      "the neutral's bounding box is centred at ({:.1f}, {:.1f}, {:.1f}) mm, "
      "{:.0f} mm from head space's origin (more than {:.0f} mm): hmc places "
      "the head at the origin of helmet space (docs/formats.md); move the "
      "neutral and its shapes so the origin is inside the head",
      centre.x(), centre.y(), centre.z(), centre.norm(), kHeadCentreMaxMm)});
}

void CheckOrientation(const Actor& actor, std::vector<ActorWarning>* out) {
  // Up: from the jaw markers (or chin, mouth) to the stable ones (or
  // forehead, brow): the head's vertical on any face hmc can stabilize.
  Vec3 upper = Vec3::Zero(), lower = Vec3::Zero();
  const bool have_upper = MeanOfTagged(actor, {"stable"}, &upper) ||
                          MeanOfTagged(actor, {"forehead", "brow"}, &upper);
  const bool have_lower = MeanOfTagged(actor, {"jaw"}, &lower) ||
                          MeanOfTagged(actor, {"chin", "mouth"}, &lower);
  const Vec3 up = upper - lower;
  if (have_upper && have_lower && up.norm() > 1e-6 &&
      AngleBetweenDeg(up, Vec3::UnitY()) > kUpMaxDeg) {
    out->push_back({"orientation", fmt::format(
        "the stable markers sit above the jaw markers along {} ({:.0f} "
        "degrees from +y): head space is +y up, +z forward, +x the actor's "
        "left (docs/formats.md); a Z-up export needs rotating",
        NearestAxis(up), AngleBetweenDeg(up, Vec3::UnitY()))});
    return;  // the forward check would repeat the same rotation
  }
  // Forward: the neutral's normals at the markers, which sit on the face.
  if (actor.markers.empty()) return;
  const MatX3d normals = VertexNormals(actor.neutral.V, actor.neutral.F);
  Vec3 forward = Vec3::Zero();
  for (const Marker& marker : actor.markers) {
    forward += EvaluateSurfacePoint(marker.point, actor.neutral.F, normals);
  }
  if (forward.norm() < 1e-9) return;
  if (AngleBetweenDeg(forward, Vec3::UnitZ()) > kForwardMaxDeg) {
    out->push_back({"orientation", fmt::format(
        "the face (the neutral's normals at the markers) looks along {} "
        "({:.0f} degrees from +z): head space is +y up, +z forward, +x the "
        "actor's left (docs/formats.md)",
        NearestAxis(forward), AngleBetweenDeg(forward, Vec3::UnitZ()))});
  }
}

void CheckUnits(const Actor& actor, std::vector<ActorWarning>* out) {
  const Eigen::Matrix<double, 2, 3> box = BoundingBox(actor.neutral.V);
  const double size = (box.row(1) - box.row(0)).maxCoeff();  // mm, as loaded
  if (size >= kHeadSizeMinMm && size <= kHeadSizeMaxMm) return;
  // What the numbers in the files would make the head in each unit.
  const double declared = actor.units == "cm" ? 10.0 : 1.0;  // mm per file unit
  const double raw = size / declared;
  std::string guess;
  double best = 1e300;
  for (const auto& [unit, scale] : {std::make_pair("mm", 1.0), std::make_pair("cm", 10.0),
                                    std::make_pair("m", 1000.0)}) {
    const double as = raw * scale;
    const double off = std::abs(std::log(as / 200.0));  // a head ~200 mm
    if (as >= kHeadSizeMinMm && as <= kHeadSizeMaxMm && off < best) {
      best = off;
      guess = unit;
    }
  }
  std::string hint = "check the OBJs' scale";
  if (guess == "m") {
    hint = "the files look like metres: hmc reads mm or cm, scale them by 1000";
  } else if (!guess.empty()) {
    hint = fmt::format("the files look like {}: set `units: {}` in actor.yaml", guess, guess);
  }
  out->push_back({"units", fmt::format(
      "the neutral is {:.3g} mm across at `units: {}` (a face is ~150-250 mm "
      "tall; expected {:.0f}-{:.0f} mm): {}",
      size, actor.units, kHeadSizeMinMm, kHeadSizeMaxMm, hint)});
}

void CheckTags(const Actor& actor, std::vector<ActorWarning>* out) {
  std::vector<std::string> known = KnownMarkerTags();
  for (const Shape& shape : actor.shapes) {
    for (const std::string& tag : shape.tags) {
      if (std::find(known.begin(), known.end(), tag) == known.end()) known.push_back(tag);
    }
  }
  std::map<std::string, std::vector<std::string>> unknown;  // tag -> markers
  for (const Marker& marker : actor.markers) {
    for (const std::string& tag : marker.tags) {
      if (std::find(known.begin(), known.end(), tag) == known.end()) {
        unknown[tag].push_back(marker.name);
      }
    }
  }
  for (const auto& [tag, markers] : unknown) {
    std::string names;
    for (size_t i = 0; i < markers.size() && i < 5; ++i) {
      names += (i ? ", " : "") + markers[i];
    }
    if (markers.size() > 5) names += fmt::format(" and {} more", markers.size() - 5);
    out->push_back({"tag", fmt::format(
        "{} {}: unknown tag '{}' (nearest known tag: '{}'); hmc reads "
        "stable, jaw and lower_lip, and region tags only where a shape has "
        "them too (docs/formats.md, markers.csv)",
        markers.size() == 1 ? "marker" : "markers", names, tag,
        NearestTag(tag, KnownMarkerTags()))});
  }
}

}  // namespace

const std::vector<std::string>& KnownMarkerTags() {
  static const std::vector<std::string> tags = {
      "stable", "jaw",     "lower_lip", "forehead", "brow",  "eye_l",
      "eye_r",  "nose",    "cheek_l",   "cheek_r",  "mouth", "chin"};
  return tags;
}

std::string NearestTag(const std::string& tag, const std::vector<std::string>& known) {
  return NearestWord(tag, known, 1 << 20);
}

std::vector<ActorWarning> ActorWarnings(const Actor& actor) {
  std::vector<ActorWarning> out;
  CheckOrigin(actor, &out);
  CheckOrientation(actor, &out);
  CheckUnits(actor, &out);
  CheckTags(actor, &out);
  return out;
}

}  // namespace hmc
