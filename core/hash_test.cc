#include "core/hash.h"

#include <random>
#include <string>

#include <gtest/gtest.h>

#include "core/file_util.h"
#include "core/temp_dir.h"

namespace hmc {
namespace {

// The word-wise FNV-1a written out plainly: words, then tail bytes, then
// the length (the actor package's content hash, docs/formats.md).
uint64_t Reference(const std::string& s) {
  uint64_t h = 14695981039346656037ull;
  const uint64_t p = 1099511628211ull;
  size_t w = 0;
  for (; w + 8 <= s.size(); w += 8) {
    uint64_t word = 0;
    for (int i = 7; i >= 0; --i) word = (word << 8) | static_cast<unsigned char>(s[w + i]);
    h = (h ^ word) * p;
  }
  for (; w < s.size(); ++w) h = (h ^ static_cast<unsigned char>(s[w])) * p;
  return (h ^ s.size()) * p;
}

TEST(HashTest, AnySplitOfTheBytesGivesTheSameHash) {
  std::mt19937 rng(3);
  for (int trial = 0; trial < 50; ++trial) {
    std::string s(rng() % 100, '\0');
    for (char& c : s) c = static_cast<char>(rng());
    ContentHasher split;
    size_t pos = 0;
    while (pos < s.size()) {
      const size_t n = std::min<size_t>(rng() % 13, s.size() - pos);
      split.Update(std::string_view(s).substr(pos, n));
      pos += n;
    }
    EXPECT_EQ(split.Digest(), Reference(s));
    EXPECT_EQ(HashBytes(s), Reference(s));
  }
}

TEST(HashTest, FilesHashTheirBytesAndDifferOnAnyChange) {
  TempDir dir;
  std::string big(3 * (1 << 20) + 5, 'a');
  WriteFileAtomic(dir.path() / "f", big);
  EXPECT_EQ(HashFile(dir.path() / "f"), HashBytes(big));
  big[2 * (1 << 20)] = 'b';
  WriteFileAtomic(dir.path() / "f", big);
  EXPECT_EQ(HashFile(dir.path() / "f"), HashBytes(big));
  EXPECT_NE(HashBytes("ab"), HashBytes("ba"));
  EXPECT_NE(HashBytes(""), HashBytes(std::string(1, '\0')));
  EXPECT_EQ(HashHex(0xabc).size(), 16u);
}

}  // namespace
}  // namespace hmc
