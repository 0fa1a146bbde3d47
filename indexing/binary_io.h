// Little helpers for the index cache's binary format (native little-endian
// PODs, length-prefixed vectors). A short read throws InputError; the cache
// loader turns that into "rebuild".
#pragma once

#include <cstdint>
#include <istream>
#include <ostream>
#include <type_traits>
#include <vector>

#include "core/error.h"

namespace hmc {

template <typename T>
void WritePod(std::ostream& out, const T& value) {
  static_assert(std::is_trivially_copyable_v<T>);
  out.write(reinterpret_cast<const char*>(&value), sizeof(T));
}

template <typename T>
T ReadPod(std::istream& in) {
  static_assert(std::is_trivially_copyable_v<T>);
  T value;
  in.read(reinterpret_cast<char*>(&value), sizeof(T));
  if (!in) throw InputError("index cache: unexpected end of file");
  return value;
}

template <typename T>
void WritePodVector(std::ostream& out, const std::vector<T>& values) {
  static_assert(std::is_trivially_copyable_v<T>);
  WritePod<uint64_t>(out, values.size());
  out.write(reinterpret_cast<const char*>(values.data()),
            static_cast<std::streamsize>(values.size() * sizeof(T)));
}

template <typename T>
std::vector<T> ReadPodVector(std::istream& in, uint64_t max_size = 1ull << 34) {
  static_assert(std::is_trivially_copyable_v<T>);
  const uint64_t n = ReadPod<uint64_t>(in);
  if (n > max_size / sizeof(T)) {
    throw InputError("index cache: implausible array size");
  }
  std::vector<T> values(n);
  in.read(reinterpret_cast<char*>(values.data()),
          static_cast<std::streamsize>(n * sizeof(T)));
  if (!in) throw InputError("index cache: unexpected end of file");
  return values;
}

}  // namespace hmc
