// Little helpers for the index cache's binary format (native little-endian
// numbers, length-prefixed vectors; docs/formats.md, "lgi_index.bin"). A
// short read throws InputError; the cache loader turns that into "rebuild".
// Only types without padding bytes may be written whole (numbers, arrays
// and structs of one number type): a padded struct would write whatever its
// padding held, and two builds of the same index would differ (issue 24,
// item 11). Structs with padding are written field by field.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <istream>
#include <ostream>
#include <type_traits>
#include <vector>

#include "core/error.h"

namespace hmc {

// Whether every byte of a T is a byte of its value (no padding).
template <typename T>
constexpr bool kPaddingFree = std::is_arithmetic_v<T> ||
                              std::has_unique_object_representations_v<T>;

template <typename T>
void WritePod(std::ostream& out, const T& value) {
  static_assert(std::is_trivially_copyable_v<T>);
  static_assert(kPaddingFree<T>, "write padded structs field by field");
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
  static_assert(kPaddingFree<T>, "write padded structs field by field");
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
  // Read in chunks, so a lying count fails at the end of the file instead
  // of allocating what it claims first.
  std::vector<T> values;
  constexpr uint64_t kChunk = (1u << 20) / sizeof(T) + 1;
  for (uint64_t done = 0; done < n;) {
    const uint64_t take = std::min(kChunk, n - done);
    values.resize(done + take);
    in.read(reinterpret_cast<char*>(values.data() + done),
            static_cast<std::streamsize>(take * sizeof(T)));
    if (!in) throw InputError("index cache: unexpected end of file");
    done += take;
  }
  return values;
}

}  // namespace hmc
