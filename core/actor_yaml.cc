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
#include "core/options.h"
#include "core/logging.h"
#include "core/obj_io.h"
#include "core/parallel.h"
#include "core/triangle.h"

namespace hmc::actor_io {

namespace {

// ---------------------------------------------------------------------------
// actor.yaml

int LineOf(const YAML::Node& node) {
  const YAML::Mark mark = node.Mark();
  return mark.line >= 0 ? mark.line + 1 : 0;
}

template <typename... Args>
[[noreturn]] void FailAt(const fs::path& file, const YAML::Node& node,
                         fmt::format_string<Args...> format, Args&&... args) {
  ThrowInputError(file, LineOf(node), format, std::forward<Args>(args)...);
}

// Checks that `node` is a mapping whose keys are all in `allowed`, each once.
void CheckKeys(const YAML::Node& node, const fs::path& file, const char* what,
               std::initializer_list<const char*> allowed) {
  if (!node.IsMap()) FailAt(file, node, "{} must be a mapping of keys", what);
  std::set<std::string> seen;
  for (const auto& item : node) {
    const std::string key = item.first.Scalar();
    bool known = false;
    for (const char* name : allowed) known = known || key == name;
    if (!known) {
      std::string list;
      for (const char* name : allowed) {
        list += list.empty() ? "" : ", ";
        list += name;
      }
      FailAt(file, item.first, "unknown key '{}' in {} (allowed: {})", key,
             what, list);
    }
    if (!seen.insert(key).second) {
      FailAt(file, item.first, "key '{}' appears twice in {}", key, what);
    }
  }
}

YAML::Node Require(const YAML::Node& map, const char* key, const fs::path& file,
                   const char* what) {
  const YAML::Node node = map[key];
  if (!node) FailAt(file, map, "{} lacks the required key '{}'", what, key);
  return node;
}

std::string GetString(const YAML::Node& node, const fs::path& file,
                      const char* what) {
  if (!node.IsScalar() || node.Scalar().empty()) {
    FailAt(file, node, "{} must be a non-empty string", what);
  }
  return node.Scalar();
}

double GetNumber(const YAML::Node& node, const fs::path& file,
                 const char* what) {
  double value = 0;
  if (!node.IsScalar() || !ParseDouble(Trim(node.Scalar()), &value)) {
    // yaml-cpp's as<double>() would also take ".nan" and ".inf"; the
    // package wants plain finite numbers only.
    FailAt(file, node, "{} must be a number, got '{}'", what,
           node.IsScalar() ? node.Scalar() : std::string("(not a scalar)"));
  }
  if (!std::isfinite(value)) {
    FailAt(file, node, "{} must be a finite number, got '{}'", what,
           node.Scalar());
  }
  return value;
}

Vec3 GetVec3(const YAML::Node& node, const fs::path& file, const char* what) {
  if (!node.IsSequence() || node.size() != 3) {
    FailAt(file, node, "{} must be a list of 3 numbers [x, y, z]", what);
  }
  Vec3 v;
  for (int i = 0; i < 3; ++i) v[i] = GetNumber(node[i], file, what);
  return v;
}

std::vector<std::string> GetTags(const YAML::Node& node, const fs::path& file,
                                 const char* what) {
  if (!node.IsSequence()) FailAt(file, node, "{} must be a list of tags", what);
  std::vector<std::string> tags;
  for (const auto& item : node) {
    const std::string tag = GetString(item, file, what);
    if (!IsValidName(tag)) {
      FailAt(file, item, "tag '{}' in {} is not a valid name ({})", tag, what,
             kNameRule);
    }
    tags.push_back(tag);
  }
  return tags;
}

}  // namespace

PackageEntry ParseActorYaml(const std::string& text, const fs::path& file) {
  const YAML::Node root_node = ParseYaml(text, file);
  const YAML::Node& root = root_node;
  if (!root.IsMap()) ThrowInputError(file, 0, "must be a YAML mapping of keys");
  CheckKeys(root, file, "actor.yaml",
            {"version", "name", "units", "neutral", "markers", "shapes",
             "jaw_rig"});
  if (const YAML::Node version = root["version"]) {
    if (GetNumber(version, file, "version") != 1) {
      FailAt(file, version, "unsupported package version '{}' (this hmc reads 1)",
             version.Scalar());
    }
  }
  PackageEntry entry;
  entry.name = GetString(Require(root, "name", file, "actor.yaml"), file, "name");
  const YAML::Node units = Require(root, "units", file, "actor.yaml");
  entry.units = GetString(units, file, "units");
  if (entry.units != "mm" && entry.units != "cm") {
    FailAt(file, units, "units must be 'mm' or 'cm', got '{}'", entry.units);
  }
  entry.neutral = GetString(Require(root, "neutral", file, "actor.yaml"), file,
                            "neutral");
  entry.markers = GetString(Require(root, "markers", file, "actor.yaml"), file,
                            "markers");

  if (const YAML::Node shapes = root["shapes"]) {
    if (!shapes.IsSequence() && !shapes.IsNull()) {
      FailAt(file, shapes, "shapes must be a list");
    }
    std::map<std::string, int> shape_lines;
    for (const auto& item : shapes) {
      CheckKeys(item, file, "a shape", {"name", "file", "jaw", "tags"});
      ShapeEntry shape;
      shape.line = LineOf(item);
      const YAML::Node name = Require(item, "name", file, "a shape");
      shape.name = GetString(name, file, "shape name");
      if (!IsValidName(shape.name)) {
        FailAt(file, name, "shape name '{}' is not a valid name ({})",
               shape.name, kNameRule);
      }
      const auto [it, inserted] = shape_lines.emplace(shape.name, shape.line);
      if (!inserted) {
        FailAt(file, name, "duplicate shape name '{}' (first on line {})",
               shape.name, it->second);
      }
      if (const YAML::Node shape_file = item["file"]) {
        shape.file = GetString(shape_file, file, "shape file");
      } else {
        shape.file = fs::path("shapes") / (shape.name + ".obj");
      }
      if (const YAML::Node jaw = item["jaw"]) {
        const auto& names = JawPose::ParameterNames();
        CheckKeys(jaw, file, "a shape's jaw pose",
                  {names[0].c_str(), names[1].c_str(), names[2].c_str()});
        std::array<double, 3> values = {0, 0, 0};
        for (int i = 0; i < 3; ++i) {
          if (const YAML::Node value = jaw[names[i]]) {
            values[i] = GetNumber(value, file, names[i].c_str());
          }
        }
        shape.jaw = JawPose::FromArray(values);
      }
      if (const YAML::Node tags = item["tags"]) {
        shape.tags = GetTags(tags, file, "shape tags");
      }
      entry.shapes.push_back(std::move(shape));
    }
  }

  if (const YAML::Node rig = root["jaw_rig"]) {
    CheckKeys(rig, file, "jaw_rig",
              {"pivot", "hinge", "vertical", "forward", "weights"});
    JawRigEntry jaw;
    jaw.line = LineOf(rig);
    jaw.pivot = GetVec3(Require(rig, "pivot", file, "jaw_rig"), file,
                        "jaw_rig pivot");
    const char* axis_names[3] = {"hinge", "vertical", "forward"};
    for (int i = 0; i < 3; ++i) {
      jaw.axes.col(i) = GetVec3(Require(rig, axis_names[i], file, "jaw_rig"),
                                file, axis_names[i]);
    }
    const Mat3 gram = jaw.axes.transpose() * jaw.axes;
    if ((gram - Mat3::Identity()).cwiseAbs().maxCoeff() > kAxesTolerance ||
        jaw.axes.determinant() <= 0) {
      FailAt(file, rig,
             "jaw_rig axes hinge, vertical, forward must be orthonormal and "
             "right-handed (hinge x vertical = forward)");
    }
    // Snap to the nearest rotation, so rounding in the file does not make
    // the jaw transform slightly non-rigid.
    Eigen::JacobiSVD<Mat3> svd(jaw.axes, Eigen::ComputeFullU | Eigen::ComputeFullV);
    jaw.axes = svd.matrixU() * svd.matrixV().transpose();
    jaw.weights = GetString(Require(rig, "weights", file, "jaw_rig"), file,
                            "jaw_rig weights");
    entry.jaw_rig = jaw;
  }
  for (const ShapeEntry& shape : entry.shapes) {
    if (!entry.jaw_rig && !shape.jaw.IsZero()) {
      ThrowInputError(file, shape.line,
                      "shape '{}' has a jaw pose but the package has no "
                      "jaw_rig",
                      shape.name);
    }
  }
  return entry;
}

}  // namespace hmc::actor_io
