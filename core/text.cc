#include "core/text.h"

#include <algorithm>
#include <charconv>
#include <cstdint>
#include <cmath>
#include <cstring>

#include <fmt/ranges.h>

namespace hmc {

std::string Base64Encode(const void* data, size_t size) {
  static const char* table = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  const auto* bytes = static_cast<const unsigned char*>(data);
  std::string out;
  out.reserve((size + 2) / 3 * 4);
  for (size_t i = 0; i < size; i += 3) {
    const uint32_t b = (uint32_t(bytes[i]) << 16) | (i + 1 < size ? uint32_t(bytes[i + 1]) << 8 : 0) |
                       (i + 2 < size ? uint32_t(bytes[i + 2]) : 0);
    out += table[(b >> 18) & 63];
    out += table[(b >> 12) & 63];
    out += i + 1 < size ? table[(b >> 6) & 63] : '=';
    out += i + 2 < size ? table[b & 63] : '=';
  }
  return out;
}

namespace {

// from_chars does not take the '+' that people and some writers put in.
template <typename T>
bool ParseWhole(std::string_view token, T* value) {
  const char* begin = token.data();
  const char* end = begin + token.size();
  if (begin < end && *begin == '+') ++begin;
  if (begin == end) return false;
  const auto [ptr, error] = std::from_chars(begin, end, *value);
  return error == std::errc() && ptr == end;
}

bool IsBlank(char c) { return c == ' ' || c == '\t' || c == '\r'; }

}  // namespace

bool ParseDouble(std::string_view token, double* value) {
  return ParseWhole(token, value);
}
bool ParseInteger(std::string_view token, long long* value) {
  return ParseWhole(token, value);
}
bool ParseInt(std::string_view token, int* value) {
  return ParseWhole(token, value);
}

std::string_view Trim(std::string_view s) {
  while (!s.empty() && IsBlank(s.front())) s.remove_prefix(1);
  while (!s.empty() && IsBlank(s.back())) s.remove_suffix(1);
  return s;
}

std::vector<std::string_view> SplitWhitespace(std::string_view s) {
  std::vector<std::string_view> parts;
  size_t i = 0;
  while (i < s.size()) {
    while (i < s.size() && (s[i] == ' ' || s[i] == '\t')) ++i;
    const size_t start = i;
    while (i < s.size() && s[i] != ' ' && s[i] != '\t') ++i;
    if (i > start) parts.push_back(s.substr(start, i - start));
  }
  return parts;
}

std::string_view StripBom(std::string_view text) {
  if (text.size() >= 3 && std::memcmp(text.data(), "\xEF\xBB\xBF", 3) == 0) {
    text.remove_prefix(3);
  }
  return text;
}

std::vector<std::string> SplitCsvRecord(std::string_view line,
                                        const std::filesystem::path& file,
                                        int line_number) {
  std::vector<std::string> fields(1);
  bool quoted = false;
  for (size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (quoted) {
      if (c == '"' && i + 1 < line.size() && line[i + 1] == '"') {
        fields.back() += '"';
        ++i;
      } else if (c == '"') {
        quoted = false;
      } else {
        fields.back() += c;
      }
    } else if (c == '"') {
      quoted = true;
    } else if (c == ',') {
      fields.emplace_back();
    } else {
      fields.back() += c;
    }
  }
  if (quoted) ThrowInputError(file, line_number, "unterminated quoted field");
  for (std::string& field : fields) field = std::string(Trim(field));
  return fields;
}

const std::string& CsvRow::NonEmpty(size_t column) const {
  if (fields_[column].empty()) Fail("empty {}", header_[column]);
  return fields_[column];
}

int CsvRow::Int(size_t column) const {
  int value = 0;
  if (!ParseInt(fields_[column], &value)) {
    Fail("{} '{}' is not an integer", header_[column], fields_[column]);
  }
  return value;
}

double CsvRow::Finite(size_t column) const {
  double value = 0;
  if (!ParseDouble(fields_[column], &value)) {
    Fail("{} '{}' is not a number", header_[column], fields_[column]);
  }
  if (!std::isfinite(value)) {
    Fail("{} is {} (must be finite)", header_[column], fields_[column]);
  }
  return value;
}

namespace text_internal {

void CheckHeader(const std::vector<std::string>& fields,
                 const std::vector<std::string>& header,
                 const std::filesystem::path& path, int line) {
  if (fields != header) {
    ThrowInputError(path, line, "bad header '{}': expected '{}'",
                    fmt::join(fields, ","), fmt::join(header, ","));
  }
}

void ThrowFieldCount(const std::vector<std::string>& header, size_t found,
                     const std::filesystem::path& path, int line) {
  ThrowInputError(path, line, "expected {} fields ({}), found {}",
                  header.size(), fmt::join(header, ","), found);
}

void ThrowNoHeader(const std::vector<std::string>& header,
                   const std::filesystem::path& path) {
  ThrowInputError(path, 0, "empty file: expected the header '{}'",
                  fmt::join(header, ","));
}

}  // namespace text_internal
bool IsValidUtf8(std::string_view s) {
  size_t i = 0;
  while (i < s.size()) {
    const unsigned char c = static_cast<unsigned char>(s[i]);
    int extra = 0;
    uint32_t code = 0;
    if (c < 0x80) {
      ++i;
      continue;
    } else if ((c & 0xe0) == 0xc0) {
      extra = 1;
      code = c & 0x1f;
    } else if ((c & 0xf0) == 0xe0) {
      extra = 2;
      code = c & 0x0f;
    } else if ((c & 0xf8) == 0xf0) {
      extra = 3;
      code = c & 0x07;
    } else {
      return false;
    }
    if (i + extra >= s.size()) return false;  // cut short
    for (int k = 1; k <= extra; ++k) {
      const unsigned char next = static_cast<unsigned char>(s[i + k]);
      if ((next & 0xc0) != 0x80) return false;
      code = (code << 6) | (next & 0x3f);
    }
    static const uint32_t kMin[4] = {0, 0x80, 0x800, 0x10000};
    if (code < kMin[extra] || code > 0x10ffff || (code >= 0xd800 && code <= 0xdfff)) return false;
    i += extra + 1;
  }
  return true;
}

int EditDistance(std::string_view a, std::string_view b) {
  // d[i][j]: distance of a[0, i) to b[0, j), three rows kept for the swap.
  std::vector<int> before(b.size() + 1), previous(b.size() + 1), row(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) previous[j] = static_cast<int>(j);
  for (size_t i = 1; i <= a.size(); ++i) {
    row[0] = static_cast<int>(i);
    for (size_t j = 1; j <= b.size(); ++j) {
      row[j] = std::min({previous[j] + 1, row[j - 1] + 1,
                         previous[j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1)});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1]) {
        row[j] = std::min(row[j], before[j - 2] + 1);
      }
    }
    std::swap(before, previous);
    std::swap(previous, row);
  }
  return previous[b.size()];
}

std::string NearestWord(std::string_view word, const std::vector<std::string>& candidates,
                        int max_distance) {
  std::string best;
  int best_distance = max_distance + 1;
  for (const std::string& c : candidates) {
    const int d = EditDistance(word, c);
    if (d < best_distance) {
      best_distance = d;
      best = c;
    }
  }
  return best;
}

}  // namespace hmc
