// Reading typed values out of parsed YAML (yaml-cpp) with errors that name
// the file, the line and the key: for the readers of calibration.yaml and
// the Kalibr camchain (core/calibration.h, core/kalibr.h).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <yaml-cpp/yaml.h>

namespace hmc::yaml_values {

// The largest image side (px) a rig file may give: larger is not a camera,
// and the bound keeps every size conversion to int defined.
constexpr int kMaxImageSide = 65536;

// map[key]; InputError "missing key 'where.key'" when absent.
YAML::Node Required(const YAML::Node& map, const std::string& where, const char* key,
                    const std::filesystem::path& path);

// A sequence of exactly `count` finite numbers.
std::vector<double> Numbers(const YAML::Node& node, size_t count, const std::string& key,
                            const std::filesystem::path& path);

// A scalar as a string.
std::string Text(const YAML::Node& node, const std::string& key, const std::filesystem::path& path);

// An integer in [lo, hi] (a number outside int's range is refused, never
// converted).
int Integer(const YAML::Node& node, const std::string& key, int lo, int hi,
            const std::filesystem::path& path);

// A finite number.
double Number(const YAML::Node& node, const std::string& key, const std::filesystem::path& path);

}  // namespace hmc::yaml_values
