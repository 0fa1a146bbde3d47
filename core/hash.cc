#include "core/hash.h"

#include <cstring>
#include <fstream>
#include <vector>

#include <fmt/format.h>

#include "core/error.h"

namespace hmc {
namespace {
constexpr uint64_t kFnvPrime = 1099511628211ull;
}  // namespace

void ContentHasher::Update(std::string_view bytes) {
  const auto* data = reinterpret_cast<const unsigned char*>(bytes.data());
  size_t n = bytes.size();
  size_ += n;
  // Complete a pending partial word first.
  while (num_pending_ > 0 && num_pending_ < 8 && n > 0) {
    pending_[num_pending_++] = *data++;
    --n;
  }
  if (num_pending_ == 8) {
    uint64_t word;
    std::memcpy(&word, pending_, 8);  // host order: x86 and ARM are LE
    hash_ = (hash_ ^ word) * kFnvPrime;
    num_pending_ = 0;
  }
  while (n >= 8) {
    uint64_t word;
    std::memcpy(&word, data, 8);
    hash_ = (hash_ ^ word) * kFnvPrime;
    data += 8;
    n -= 8;
  }
  while (n > 0) {
    pending_[num_pending_++] = *data++;
    --n;
  }
}

uint64_t ContentHasher::Digest() const {
  uint64_t hash = hash_;
  for (size_t i = 0; i < num_pending_; ++i) hash = (hash ^ pending_[i]) * kFnvPrime;
  return (hash ^ size_) * kFnvPrime;
}

uint64_t HashBytes(std::string_view bytes) {
  ContentHasher hasher;
  hasher.Update(bytes);
  return hasher.Digest();
}

uint64_t HashFile(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) ThrowInputError(path, 0, "cannot read the file to hash it");
  ContentHasher hasher;
  std::vector<char> buffer(1 << 20);
  while (in) {
    in.read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
    const std::streamsize got = in.gcount();
    if (got > 0) hasher.Update(std::string_view(buffer.data(), static_cast<size_t>(got)));
  }
  if (in.bad()) ThrowInputError(path, 0, "read error while hashing");
  return hasher.Digest();
}

std::string HashHex(uint64_t hash) { return fmt::format("{:016x}", hash); }

}  // namespace hmc
