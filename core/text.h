// The one text module: line splitting, CSV records, whole-token numbers and
// line-numbered errors, used by every reader of a text file (bundles.csv,
// jaw.csv, markers.csv, OBJ, tracks_2d.csv, rays.csv, ...). Formats:
// docs/formats.md.
//
// Rules shared by every reader:
//  - a UTF-8 byte-order mark at the start of the file is skipped;
//  - lines end in \n or \r\n; line numbers are 1-based;
//  - numbers are parsed whole and locale-independently (std::from_chars,
//    exact for doubles), a leading '+' is accepted, surrounding blanks are
//    the caller's to trim;
//  - CSV records follow RFC 4180 quoting (as spreadsheets write it), and
//    every field is trimmed of surrounding blanks.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "core/error.h"
#include "core/file_util.h"

namespace hmc {

// Standard base64 (RFC 4648, with '=' padding) of `size` bytes: pictures
// embedded in a page, binary data in the review's scripts.
std::string Base64Encode(const void* data, size_t size);

// Whole-token parses: false unless all of `token` is the number.
bool ParseDouble(std::string_view token, double* value);
bool ParseInteger(std::string_view token, long long* value);
bool ParseInt(std::string_view token, int* value);

// `s` without leading and trailing blanks, tabs and carriage returns.
std::string_view Trim(std::string_view s);

// True if `s` is well-formed UTF-8 (no overlong forms, surrogates or code
// points above U+10FFFF): what a JSON file can hold as a string.
bool IsValidUtf8(std::string_view s);

// The blank- or tab-separated tokens of `s`.
std::vector<std::string_view> SplitWhitespace(std::string_view s);

// `text` without a leading UTF-8 byte-order mark.
std::string_view StripBom(std::string_view text);

// Levenshtein distance (insert, delete, substitute) with a swap of two
// neighbouring characters counting as one edit ("fsp" -> "fps": 1).
int EditDistance(std::string_view a, std::string_view b);
// The candidate nearest to `word` by EditDistance, or "" when none is
// within `max_distance` (ties: the first). For "did you mean ...?".
std::string NearestWord(std::string_view word, const std::vector<std::string>& candidates,
                        int max_distance);

// Calls body(line_number, line) for every line of `text` (BOM stripped,
// '\r' of \r\n removed), blank lines included.
template <typename Body>
void ForEachLine(std::string_view text, const Body& body) {
  text = StripBom(text);
  int line = 0;
  size_t pos = 0;
  while (pos < text.size()) {
    ++line;
    size_t end = text.find('\n', pos);
    if (end == std::string_view::npos) end = text.size();
    std::string_view content = text.substr(pos, end - pos);
    if (!content.empty() && content.back() == '\r') content.remove_suffix(1);
    body(line, content);
    pos = end + 1;
  }
}

// One CSV record of one line (RFC 4180 quoting; a quoted field cannot span
// lines), each field trimmed. Throws InputError at file:line on an
// unterminated quote.
std::vector<std::string> SplitCsvRecord(std::string_view line,
                                        const std::filesystem::path& file,
                                        int line_number);

// One data row of a CSV table, with the context to parse its fields and
// name the place of a bad one.
class CsvRow {
 public:
  CsvRow(const std::filesystem::path& file, int line,
         const std::vector<std::string>& header,
         const std::vector<std::string>& fields)
      : file_(file), line_(line), header_(header), fields_(fields) {}

  const std::filesystem::path& file() const { return file_; }
  int line() const { return line_; }
  size_t size() const { return fields_.size(); }

  // Field `column` as it is (trimmed).
  const std::string& Text(size_t column) const { return fields_[column]; }
  // Field `column` as a non-empty string.
  const std::string& NonEmpty(size_t column) const;
  // Field `column` as an int / a finite double; throws InputError naming
  // the file, the line, the column and the value otherwise.
  int Int(size_t column) const;
  double Finite(size_t column) const;
  // True if field `column` is empty (an optional value).
  bool Empty(size_t column) const { return fields_[column].empty(); }

  // Throws InputError at this row's file and line.
  template <typename... Args>
  [[noreturn]] void Fail(fmt::format_string<Args...> format,
                         Args&&... args) const {
    ThrowInputError(file_, line_, format, std::forward<Args>(args)...);
  }

 private:
  const std::filesystem::path& file_;
  int line_;
  const std::vector<std::string>& header_;
  const std::vector<std::string>& fields_;
};

// Reads the CSV file `path` whose first non-blank line must be exactly
// `header` and calls row(const CsvRow&) for every following non-blank line,
// which must have as many fields as the header. Throws InputError naming
// the file and line for a missing or wrong header, a wrong field count, a
// bad quote, or whatever `row` throws.
template <typename RowFn>
void ForEachCsvRow(const std::filesystem::path& path,
                   const std::vector<std::string>& header, const RowFn& row);

// The same on text already in memory (`path` names it in errors).
template <typename RowFn>
void ForEachCsvRowInText(std::string_view text,
                         const std::filesystem::path& path,
                         const std::vector<std::string>& header,
                         const RowFn& row);

// Implementation details below.
namespace text_internal {
// Throws unless `fields` equals `header`.
void CheckHeader(const std::vector<std::string>& fields,
                 const std::vector<std::string>& header,
                 const std::filesystem::path& path, int line);
[[noreturn]] void ThrowFieldCount(const std::vector<std::string>& header,
                                  size_t found,
                                  const std::filesystem::path& path, int line);
[[noreturn]] void ThrowNoHeader(const std::vector<std::string>& header,
                                const std::filesystem::path& path);
}  // namespace text_internal

template <typename RowFn>
void ForEachCsvRowInText(std::string_view text,
                         const std::filesystem::path& path,
                         const std::vector<std::string>& header,
                         const RowFn& row) {
  bool header_seen = false;
  ForEachLine(text, [&](int line_number, std::string_view line) {
    if (Trim(line).empty()) return;
    const std::vector<std::string> fields =
        SplitCsvRecord(line, path, line_number);
    if (!header_seen) {
      text_internal::CheckHeader(fields, header, path, line_number);
      header_seen = true;
      return;
    }
    if (fields.size() != header.size()) {
      text_internal::ThrowFieldCount(header, fields.size(), path, line_number);
    }
    row(CsvRow(path, line_number, header, fields));
  });
  if (!header_seen) text_internal::ThrowNoHeader(header, path);
}

template <typename RowFn>
void ForEachCsvRow(const std::filesystem::path& path,
                   const std::vector<std::string>& header, const RowFn& row) {
  const std::string text = ReadFile(path);
  ForEachCsvRowInText(text, path, header, row);
}

}  // namespace hmc
