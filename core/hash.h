// Content hashes for caches and resumable work: 64-bit FNV-1a (Fowler, Noll,
// Vo) over 8-byte words instead of bytes (8x fewer multiplies; the tail is
// hashed bytewise, then the length). Stable across platforms and runs, and
// fast next to parsing (~2 GB/s). Not cryptographic: it only tells a cache
// that an input changed. docs/formats.md, "Content hash".
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>

namespace hmc {

class ContentHasher {
 public:
  // Feeds bytes; the result depends only on the concatenation of all the
  // bytes fed, not on how they were split.
  void Update(std::string_view bytes);
  // The hash of everything fed so far (the hasher can go on after it).
  uint64_t Digest() const;

 private:
  uint64_t hash_ = 14695981039346656037ull;
  uint64_t size_ = 0;
  unsigned char pending_[8] = {};
  size_t num_pending_ = 0;
};

uint64_t HashBytes(std::string_view bytes);
// The hash of a file's bytes, read in chunks (large videos need no memory).
// Throws InputError naming `path` if it cannot be read.
uint64_t HashFile(const std::filesystem::path& path);
// 16 lower-case hex digits.
std::string HashHex(uint64_t hash);

}  // namespace hmc
