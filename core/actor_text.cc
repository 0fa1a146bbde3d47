#include "core/actor_io.h"

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

namespace hmc::actor_io {

uint64_t Fnv1a(std::string_view bytes, uint64_t hash) {
  const auto* data = reinterpret_cast<const unsigned char*>(bytes.data());
  const size_t num_words = bytes.size() / 8;
  for (size_t w = 0; w < num_words; ++w) {
    uint64_t word;
    std::memcpy(&word, data + 8 * w, 8);  // Host order: x86 and ARM are LE.
    hash ^= word;
    hash *= kFnvPrime;
  }
  for (size_t i = 8 * num_words; i < bytes.size(); ++i) {
    hash ^= data[i];
    hash *= kFnvPrime;
  }
  hash ^= bytes.size();
  hash *= kFnvPrime;
  return hash;
}

uint64_t CombineHash(uint64_t hash, const std::string& name, uint64_t file_hash) {
  hash = Fnv1a(name, hash);
  hash = Fnv1a(std::string_view("\0", 1), hash);
  char bytes[8];
  for (int i = 0; i < 8; ++i) bytes[i] = static_cast<char>(file_hash >> (8 * i));
  return Fnv1a(std::string_view(bytes, 8), hash);
}

// Names of markers, shapes and tags end up in file names (shapes), CSV
// columns and YAML keys downstream: keep them to a safe alphabet.
bool IsValidName(const std::string& name) {
  if (name.empty()) return false;
  const auto ok_first = [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') ||
           (c >= '0' && c <= '9') || c == '_';
  };
  if (!ok_first(name[0])) return false;
  for (const char c : name) {
    if (!ok_first(c) && c != '.' && c != '-') return false;
  }
  return true;
}



}  // namespace hmc::actor_io
