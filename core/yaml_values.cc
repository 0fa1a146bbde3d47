#include "core/yaml_values.h"

#include <cmath>

#include "core/error.h"

namespace hmc::yaml_values {

YAML::Node Required(const YAML::Node& map, const std::string& where, const char* key,
                    const std::filesystem::path& path) {
  const YAML::Node node = map.IsMap() ? map[key] : YAML::Node();
  if (!node) {
    ThrowInputError(path, map.Mark().line + 1, "missing key '{}.{}'", where, key);
  }
  return node;
}

double Number(const YAML::Node& node, const std::string& key, const std::filesystem::path& path) {
  double x = 0;
  try {
    x = node.as<double>();
  } catch (const YAML::Exception&) {
    ThrowInputError(path, node.Mark().line + 1, "'{}' holds a value that is not a number", key);
  }
  if (!std::isfinite(x)) ThrowInputError(path, node.Mark().line + 1, "'{}' is not finite", key);
  return x;
}

std::vector<double> Numbers(const YAML::Node& node, size_t count, const std::string& key,
                            const std::filesystem::path& path) {
  if (!node.IsSequence() || node.size() != count) {
    ThrowInputError(path, node.Mark().line + 1, "'{}' must be a list of {} numbers", key, count);
  }
  std::vector<double> out;
  for (const YAML::Node& v : node) out.push_back(Number(v, key, path));
  return out;
}

std::string Text(const YAML::Node& node, const std::string& key, const std::filesystem::path& path) {
  if (!node.IsScalar()) ThrowInputError(path, node.Mark().line + 1, "'{}' must be a string", key);
  return node.Scalar();
}

int Integer(const YAML::Node& node, const std::string& key, int lo, int hi,
            const std::filesystem::path& path) {
  const double x = Number(node, key, path);
  if (!(x >= lo && x <= hi) || x != std::floor(x)) {
    ThrowInputError(path, node.Mark().line + 1, "'{}' must be an integer from {} to {}", key, lo,
                    hi);
  }
  return static_cast<int>(x);
}

}  // namespace hmc::yaml_values
