// `hmc actor check DIR [--json]`: loads and validates an actor package and
// summarises it. A bad package fails like every other command on bad input
// (InputError -> exit code 2, the message names the file and line); a valid
// one that looks like an export mistake (head far from the origin or not +y
// up, units off by 10 or 1000, unknown marker tags) is summarised with
// warnings (core/actor_check.h; exit code 0). An actor without a jaw rig
// gets the one estimated from its dataset's jaw shapes reported, and
// `--write_jaw_rig OUT` writes the package with it (core/jaw_estimate.h).
#include <cstdio>
#include <map>
#include <memory>
#include <optional>
#include <string>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "apps/command.h"
#include "core/actor.h"
#include "core/actor_check.h"
#include "core/error.h"
#include "core/jaw_estimate.h"

namespace hmc {
namespace {

struct ActorSummary {
  std::map<std::string, int> marker_tags;  // tag -> number of markers
  int markers_by_vertex = 0;
  int shapes_with_jaw_pose = 0;
  int jaw_weighted_vertices = 0;           // weight > 0
  Eigen::Matrix<double, 2, 3> bbox;        // min, max (mm)
};

ActorSummary Summarise(const Actor& actor) {
  ActorSummary summary;
  for (const Marker& marker : actor.markers) {
    if (marker.vertex >= 0) ++summary.markers_by_vertex;
    for (const std::string& tag : marker.tags) ++summary.marker_tags[tag];
  }
  for (const Shape& shape : actor.shapes) {
    if (!shape.jaw.IsZero()) ++summary.shapes_with_jaw_pose;
  }
  if (actor.jaw_rig) {
    summary.jaw_weighted_vertices =
        static_cast<int>((actor.jaw_rig->weights.array() > 0).count());
  }
  summary.bbox = BoundingBox(actor.neutral.V);
  return summary;
}

nlohmann::json JsonVector(const Vec3& v) { return {v.x(), v.y(), v.z()}; }

nlohmann::json ToJson(const Actor& actor, const ActorSummary& summary,
                      const std::vector<ActorWarning>& warnings,
                      const std::optional<JawRigEstimate>& estimate) {
  nlohmann::json json;
  json["name"] = actor.name;
  json["dir"] = actor.dir.string();
  json["units"] = actor.units;
  json["vertices"] = actor.NumVertices();
  json["faces"] = actor.neutral.NumFaces();
  json["has_uvs"] = actor.neutral.HasUVs();
  json["uvs"] = actor.neutral.UV.rows();
  json["shapes"] = actor.shapes.size();
  json["shapes_with_jaw_pose"] = summary.shapes_with_jaw_pose;
  json["markers"] = actor.markers.size();
  json["markers_by_vertex"] = summary.markers_by_vertex;
  json["marker_tags"] = summary.marker_tags;
  json["has_jaw_rig"] = actor.jaw_rig.has_value();
  if (actor.jaw_rig) {
    const JawRig& rig = *actor.jaw_rig;
    json["jaw_rig"] = {
        {"pivot_mm", {rig.pivot.x(), rig.pivot.y(), rig.pivot.z()}},
        {"weighted_vertices", summary.jaw_weighted_vertices}};
  }
  // Without a jaw rig: the one estimated from the dataset's jaw shapes
  // (core/jaw_estimate.h), or null where it has none.
  if (!actor.jaw_rig) {
    json["jaw_rig_estimate"] = nullptr;
    if (estimate) {
      const JawRig& rig = estimate->rig;
      json["jaw_rig_estimate"] = {
          {"from_shapes", {{"open", estimate->open_shape},
                           {"lateral", estimate->lateral_shape},
                           {"forward", estimate->forward_shape}}},
          {"pivot_mm", JsonVector(rig.pivot)},
          {"hinge", JsonVector(rig.axes.col(0))},
          {"vertical", JsonVector(rig.axes.col(1))},
          {"forward", JsonVector(rig.axes.col(2))},
          {"weighted_vertices", (rig.weights.array() > 0).count()},
          {"shapes_with_jaw_pose", estimate->shapes_with_pose},
          {"open_fit_rms_mm", estimate->open_rms_mm}};
    }
  }
  json["bbox_mm"] = {
      {"min", {summary.bbox(0, 0), summary.bbox(0, 1), summary.bbox(0, 2)}},
      {"max", {summary.bbox(1, 0), summary.bbox(1, 1), summary.bbox(1, 2)}}};
  json["content_hash"] = fmt::format("{:016x}", actor.content_hash);
  json["warnings"] = nlohmann::json::array();
  for (const ActorWarning& w : warnings) {
    json["warnings"].push_back({{"kind", w.kind}, {"message", w.message}});
  }
  return json;
}

std::string FormatRow(const Eigen::RowVector3d& v) {
  return fmt::format("({:.2f}, {:.2f}, {:.2f})", v[0], v[1], v[2]);
}

void PrintText(const Actor& actor, const ActorSummary& summary,
               const std::vector<ActorWarning>& warnings,
               const std::optional<JawRigEstimate>& estimate) {
  std::string tags;
  for (const auto& [tag, count] : summary.marker_tags) {
    tags += fmt::format("{}{} {}", tags.empty() ? "" : ", ", tag, count);
  }
  std::string jaw = estimate ? "none; " + estimate->Describe()
                             : "none (no shape named as a jaw opening to estimate one from)";
  if (actor.jaw_rig) {
    jaw = fmt::format("pivot {} mm, {} of {} vertices weighted",
                      FormatRow(actor.jaw_rig->pivot.transpose()),
                      summary.jaw_weighted_vertices, actor.NumVertices());
  }
  const Eigen::RowVector3d size = summary.bbox.row(1) - summary.bbox.row(0);
  fmt::print(
      "actor      {}\n"
      "folder     {}\n"
      "units      {}{}\n"
      "neutral    {} vertices, {} triangles, {} UVs\n"
      "shapes     {} ({} with a jaw pose)\n"
      "markers    {} ({} on vertices){}{}\n"
      "jaw rig    {}\n"
      "bbox (mm)  min {} max {} size {}\n"
      "hash       {:016x}\n",
      actor.name, actor.dir.string(), actor.units,
      actor.units == "mm" ? "" : " (converted to mm)", actor.NumVertices(),
      actor.neutral.NumFaces(), actor.neutral.UV.rows(), actor.shapes.size(),
      summary.shapes_with_jaw_pose, actor.markers.size(),
      summary.markers_by_vertex, tags.empty() ? "" : ": ", tags, jaw,
      FormatRow(summary.bbox.row(0)), FormatRow(summary.bbox.row(1)),
      FormatRow(size), actor.content_hash);
  for (const ActorWarning& w : warnings) fmt::print("warning    {}\n", w.message);
}

}  // namespace

HMC_COMMAND(ActorCheck, "actor", "check",
            "Load and validate an actor package; print a summary") {
  auto dir = std::make_shared<std::string>();
  auto json = std::make_shared<bool>(false);
  auto write_jaw_rig = std::make_shared<std::string>();
  app->add_option("dir", *dir, "Actor package folder")->required();
  app->add_flag("--json", *json, "Print one JSON object instead of text");
  app->add_option("--write_jaw_rig", *write_jaw_rig,
                  "Write the package with the jaw rig estimated from its jaw shapes to this "
                  "folder (an actor without a jaw rig; docs/formats.md)");
  return [=] {
    Actor actor = LoadActor(*dir);
    const ActorSummary summary = Summarise(actor);
    const std::vector<ActorWarning> warnings = ActorWarnings(actor);
    for (const ActorWarning& w : warnings) spdlog::warn("actor check: {}", w.message);
    std::optional<JawRigEstimate> estimate;
    if (!actor.jaw_rig) estimate = EstimateJawRig(actor);
    if (*json) {
      std::printf("%s\n", ToJson(actor, summary, warnings, estimate).dump(2).c_str());
    } else {
      PrintText(actor, summary, warnings, estimate);
    }
    if (!write_jaw_rig->empty()) {
      if (actor.jaw_rig) {
        throw InputError(fmt::format("--write_jaw_rig: actor '{}' ({}) has a jaw rig already",
                                     actor.name, actor.dir.string()));
      }
      if (!estimate) {
        throw InputError(fmt::format(
            "--write_jaw_rig: actor '{}' ({}) has no shape named as a jaw opening (a name "
            "with 'jaw' and 'open' or 'drop') to estimate a jaw rig from",
            actor.name, actor.dir.string()));
      }
      ApplyJawRigEstimate(*estimate, &actor);
      WriteActor(actor, *write_jaw_rig);
      spdlog::info("actor check: wrote {} with the estimated jaw rig", *write_jaw_rig);
    }
    return 0;
  };
}

}  // namespace hmc
