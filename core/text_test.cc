#include "core/text.h"

#include <algorithm>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

namespace hmc {
namespace {

TEST(TextTest, NumbersParseWholeTokensOnly) {
  double d = 0;
  EXPECT_TRUE(ParseDouble("1.5", &d));
  EXPECT_EQ(d, 1.5);
  EXPECT_TRUE(ParseDouble("+2e-3", &d));
  EXPECT_EQ(d, 2e-3);
  EXPECT_TRUE(ParseDouble("-0.1", &d));
  EXPECT_EQ(d, -0.1);
  for (const char* bad : {"", "+", "1.5x", " 1", "1 ", "1,5", "--1", "0x10"}) {
    EXPECT_FALSE(ParseDouble(bad, &d)) << bad;
  }
  int i = 0;
  EXPECT_TRUE(ParseInt("+42", &i));
  EXPECT_EQ(i, 42);
  EXPECT_FALSE(ParseInt("4.2", &i));
  EXPECT_FALSE(ParseInt("99999999999", &i));  // out of range, not wrapped
  long long ll = 0;
  EXPECT_TRUE(ParseInteger("99999999999", &ll));
  EXPECT_EQ(ll, 99999999999LL);
}

TEST(TextTest, DoublesRoundTripExactly) {
  for (const double value : {0.1, 1.0 / 3.0, 1e-300, 123456.789012345678,
                             std::numeric_limits<double>::max()}) {
    double back = 0;
    ASSERT_TRUE(ParseDouble(fmt::format("{}", value), &back));
    EXPECT_EQ(back, value);
  }
}

TEST(TextTest, LinesStripBomAndCarriageReturns) {
  std::vector<std::pair<int, std::string>> lines;
  ForEachLine("\xEF\xBB\xBF" "a\r\n\nb\nc", [&](int n, std::string_view l) {
    lines.emplace_back(n, std::string(l));
  });
  const std::vector<std::pair<int, std::string>> expected = {
      {1, "a"}, {2, ""}, {3, "b"}, {4, "c"}};
  EXPECT_EQ(lines, expected);
}

TEST(TextTest, CsvRecordsFollowRfc4180AndAreTrimmed) {
  EXPECT_EQ(SplitCsvRecord(" a , \"b,c\" ,\"say \"\"hi\"\"\",", "f", 1),
            (std::vector<std::string>{"a", "b,c", "say \"hi\"", ""}));
  EXPECT_THROW(SplitCsvRecord("a,\"b", "f", 3), InputError);
}

TEST(TextTest, CsvTableChecksHeaderAndFieldCount) {
  const std::vector<std::string> header = {"frame", "x"};
  std::vector<std::pair<int, double>> rows;
  ForEachCsvRowInText("\xEF\xBB\xBF" "frame,x\n\n1,2.5\r\n3, 4\n", "t.csv",
                      header, [&](const CsvRow& row) {
                        rows.emplace_back(row.Int(0), row.Finite(1));
                      });
  EXPECT_EQ(rows, (std::vector<std::pair<int, double>>{{1, 2.5}, {3, 4}}));

  const auto message = [&](const std::string& text) {
    try {
      ForEachCsvRowInText(text, "t.csv", header, [](const CsvRow& row) {
        row.Int(0);
        row.Finite(1);
      });
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message("").find("empty file"), std::string::npos);
  EXPECT_NE(message("frame,y\n").find("bad header"), std::string::npos);
  EXPECT_NE(message("frame,x\n1\n").find("t.csv:2"), std::string::npos);
  EXPECT_NE(message("frame,x\n1,2\nx,3\n").find("t.csv:3"), std::string::npos);
  EXPECT_NE(message("frame,x\n1,nan\n").find("finite"), std::string::npos);
  EXPECT_NE(message("frame,x\n1,inf\n").find("finite"), std::string::npos);
}

// Issue 45, item 10: what JSON can hold (nlohmann throws on the rest).
TEST(TextTest, Utf8ValidityFollowsTheStandard) {
  EXPECT_TRUE(IsValidUtf8("W\xc3\xa9rk/\xe6\x97\xa5\xf0\x9f\x99\x82"));
  EXPECT_TRUE(IsValidUtf8(""));
  for (const std::string bad : {"W\xe9rk", "\xc3", "\xc0\xaf", "\xed\xa0\x80", "\xf4\x90\x80\x80",
                                "\xff", "ab\xe6\x97"}) {
    EXPECT_FALSE(IsValidUtf8(bad)) << bad;
  }
}

}  // namespace
}  // namespace hmc

namespace hmc {
namespace {

// Invariants of a distance on random words: zero only for equal words,
// symmetric, blind to a shared suffix, at most the longer length, one per
// edit; a swap of neighbours costs one (what "did you mean" relies on).
TEST(TextTest, EditDistanceIsADistanceAndCountsSwapsAsOne) {
  std::mt19937 rng(52);
  auto word = [&] {
    std::string w(std::uniform_int_distribution<int>(0, 7)(rng), 'a');
    for (char& c : w) c = static_cast<char>('a' + std::uniform_int_distribution<int>(0, 3)(rng));
    return w;
  };
  for (int trial = 0; trial < 300; ++trial) {
    const std::string a = word(), b = word(), c = word();
    EXPECT_EQ(EditDistance(a, b) == 0, a == b);
    EXPECT_EQ(EditDistance(a, b), EditDistance(b, a));
    // Restricted swaps (a string edited once only) break the triangle
    // inequality in general; appending a common suffix changes nothing.
    EXPECT_EQ(EditDistance(a + c, b + c), EditDistance(a, b));
    EXPECT_LE(EditDistance(a, b), static_cast<int>(std::max(a.size(), b.size())));
    EXPECT_LE(EditDistance(a, a + "x"), 1);
    if (a.size() >= 2) {
      std::string swapped = a;
      std::swap(swapped[0], swapped[1]);
      EXPECT_LE(EditDistance(a, swapped), 1);
    }
  }
  EXPECT_EQ(EditDistance("fsp", "fps"), 1);
  EXPECT_EQ(NearestWord("--fsp", {"--out", "--fps", "--frames"}, 2), "--fps");
  EXPECT_EQ(NearestWord("--zzzzzz", {"--out", "--fps"}, 2), "");
}

}  // namespace
}  // namespace hmc

namespace hmc {
namespace {

// RFC 4648, section 10: the standard's own test vectors.
TEST(Base64, EncodesTheRfcTestVectors) {
  const std::vector<std::pair<std::string, std::string>> vectors = {
      {"", ""}, {"f", "Zg=="}, {"fo", "Zm8="}, {"foo", "Zm9v"},
      {"foob", "Zm9vYg=="}, {"fooba", "Zm9vYmE="}, {"foobar", "Zm9vYmFy"}};
  for (const auto& [in, out] : vectors) EXPECT_EQ(Base64Encode(in.data(), in.size()), out) << in;
  const unsigned char high[] = {0xff, 0xfe, 0x00};
  EXPECT_EQ(Base64Encode(high, 3), "//4A");
}

}  // namespace
}  // namespace hmc
