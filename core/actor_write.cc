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
#include "core/day_markers.h"

namespace hmc {

using namespace actor_io;  // NOLINT(build/namespaces): this module's helpers

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

  // neutral.obj is written as triangles, so OBJ face = triangle.
  WriteFileAtomic(dir / "markers.csv", FormatMarkersCsv(actor.markers));

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
