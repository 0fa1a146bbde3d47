// One field registry per options struct drives the YAML config, the CLI
// flags and the `options_used.yaml` written next to each output
// (docs/ARCHITECTURE.md, "Contracts"). Defaults live only in the options header,
// as default member initialisers; the registry only points at the fields.
//
// An options struct provides
//   void Register(OptionFields* fields);   // each field once: name, help, range
//   bool Check() const;                     // logs the offending option
// Register declares each field with its range, so that one declaration
// gives the YAML key, the CLI flag, the options_used.yaml entry and the
// check of the range:
//   fields->Add("tolerance_mm", &tolerance_mm, "help (mm)").AtLeast(0);
//   fields->Add("fraction", &fraction, "help").In(0, 1);
//   fields->Add("loss", &loss, "none | huber").OneOf({"none", "huber"});
// Check() starts with CHECK_OPTION_LIMITS() (the declared ranges) and adds
// only what involves more than one field, with the CHECK_OPTION macros
// below (as COLMAP does):
//   bool Check() const {
//     CHECK_OPTION_LIMITS();
//     CHECK_OPTION_LE(min_frames, max_frames);
//     return true;
//   }
// Each logs the failed condition with the option's value and makes Check()
// return false. NaN fails every comparison.
//
// Value types: double, int, bool, text, and lists of numbers or of text. A
// list is a YAML sequence in a config (`noise_mm: [0, 0.5, 1]`) and comma
// separated on the command line (`--noise_mm 0,0.5,1`); options_used.yaml
// writes it as a sequence.
// Field names are snake_case; a group ("index", "blend") nests them in YAML
// (`index: {min_volume: ...}`) and prefixes the CLI flag (`--index.min_volume`).
#pragma once

#include <cmath>
#include <filesystem>
#include <functional>
#include <string>
#include <variant>
#include <vector>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <spdlog/spdlog.h>
#include <yaml-cpp/yaml.h>

#include "core/error.h"

namespace hmc {

// Parses YAML text; `file` names it in messages. Throws InputError with the
// line for invalid YAML and for a key given twice in any mapping (yaml-cpp
// would keep the last silently: `method: robust` then `method: lgi`).
YAML::Node ParseYaml(const std::string& text, const std::filesystem::path& file);
// ReadFile(file) then ParseYaml.
YAML::Node LoadYamlFile(const std::filesystem::path& file);

class OptionFields {
 public:
  using Pointer = std::variant<double*, int*, bool*, std::string*,
                               std::vector<double>*,
                               std::vector<std::string>*>;
  struct Field {
    std::string name;  // "group.name" or "name"
    std::string help;
    Pointer pointer;
    // The declared range (numbers, and each item of a list of numbers):
    // lo <= value (lo < value if lo_open), likewise hi; `choices`: the
    // values a text (or each item of a list of text) may take ({} = any).
    double lo = -HUGE_VAL, hi = HUGE_VAL;
    bool lo_open = false, hi_open = false;
    std::vector<std::string> choices;
    // Where the value was last set ("run.yaml:12", "--gate_px"; "" = the
    // default), named when it is out of range.
    mutable std::string origin;
  };

  // What Add returns: the range of the field just added, declared with it.
  class Range {
   public:
    Range(OptionFields* fields, size_t index) : fields_(fields), index_(index) {}
    Range& AtLeast(double lo);  // lo <= value
    Range& Above(double lo);    // lo < value
    Range& AtMost(double hi);   // value <= hi
    Range& Below(double hi);    // value < hi
    Range& In(double lo, double hi) { return AtLeast(lo).AtMost(hi); }
    Range& OneOf(std::vector<std::string> choices);

   private:
    Field& field() { return fields_->fields_[index_]; }
    OptionFields* fields_;
    size_t index_;
  };

  // Fields added after this call are named "<group>.<name>" ("" = no group).
  void SetGroup(std::string group) { group_ = std::move(group); }

  Range Add(const std::string& name, double* field, std::string help);
  Range Add(const std::string& name, int* field, std::string help);
  Range Add(const std::string& name, bool* field, std::string help);
  Range Add(const std::string& name, std::string* field, std::string help);
  Range Add(const std::string& name, std::vector<double>* field, std::string help);
  Range Add(const std::string& name, std::vector<std::string>* field, std::string help);

  // The first field outside its declared range, as "origin: option 'name'
  // = value must be ..." ("" = every field in range).
  // `prefix` goes before the option's name ("jaw.": a run config's section).
  std::string RangeError(const std::string& prefix = "") const;
  // The declared range in words ("in [0, 1]", ">= 0", "one of a, b"; "" = any).
  static std::string RangeText(const Field& field);

  // Sets fields from a YAML mapping (nested by group). Unknown keys, wrong
  // types and non-finite numbers throw InputError naming `file` and the line.
  void LoadYaml(const YAML::Node& root, const std::filesystem::path& file);
  void LoadYamlFile(const std::filesystem::path& file);

  // Sets one field from text, as given on the command line; `origin` names
  // where the text came from for the error message ("--index.min_volume").
  void Set(const std::string& name, const std::string& value,
           const std::string& origin);

  // Current values, nested by group; what `options_used.yaml` holds.
  YAML::Node ToYaml() const;
  std::string ValueString(const Field& field) const;

  const std::vector<Field>& fields() const { return fields_; }
  const Field* Find(const std::string& name) const;

 private:
  Range AddField(const std::string& name, Pointer pointer, std::string help);
  std::string group_;
  std::vector<Field> fields_;
};

// The CHECK_OPTION helpers for Check() bodies (see the top of this file).
#define CHECK_OPTION(condition)                                          \
  do {                                                                   \
    if (!(condition)) {                                                  \
      spdlog::error("invalid option: {} does not hold", #condition);     \
      return false;                                                      \
    }                                                                    \
  } while (0)
#define HMC_CHECK_OPTION_OP(op, a, b)                                    \
  do {                                                                   \
    if (!((a)op(b))) {                                                   \
      spdlog::error("invalid option: {} = {} must be {} {}", #a, (a), #op, \
                    (b));                                                \
      return false;                                                      \
    }                                                                    \
  } while (0)
#define CHECK_OPTION_EQ(a, b) HMC_CHECK_OPTION_OP(==, a, b)
#define CHECK_OPTION_NE(a, b) HMC_CHECK_OPTION_OP(!=, a, b)
#define CHECK_OPTION_LT(a, b) HMC_CHECK_OPTION_OP(<, a, b)
#define CHECK_OPTION_LE(a, b) HMC_CHECK_OPTION_OP(<=, a, b)
#define CHECK_OPTION_GT(a, b) HMC_CHECK_OPTION_OP(>, a, b)
#define CHECK_OPTION_GE(a, b) HMC_CHECK_OPTION_OP(>=, a, b)
// lo <= a <= hi (closed interval).
#define CHECK_OPTION_IN(a, lo, hi)                                       \
  do {                                                                   \
    if (!((a) >= (lo) && (a) <= (hi))) {                                 \
      spdlog::error("invalid option: {} = {} must be in [{}, {}]", #a,   \
                    (a), (lo), (hi));                                    \
      return false;                                                      \
    }                                                                    \
  } while (0)

// True if every field of `options` is in the range its Register declares;
// else logs the first that is not. What CHECK_OPTION_LIMITS() runs.
template <typename Options>
bool CheckDeclaredRanges(const Options& options) {
  OptionFields fields;
  // Register only takes the fields' addresses; nothing is written.
  const_cast<Options&>(options).Register(&fields);
  const std::string error = fields.RangeError();
  if (!error.empty()) spdlog::error("invalid option: {}", error);
  return error.empty();
}
#define CHECK_OPTION_LIMITS()                                            \
  do {                                                                   \
    if (!::hmc::CheckDeclaredRanges(*this)) return false;                \
  } while (0)

// Throws InputError if options.Check() fails (Check logs the reason): how a
// stage's entry point refuses invalid options.
template <typename Options>
void RequireValid(const Options& options, const char* what) {
  if (!options.Check()) {
    throw InputError(std::string("invalid ") + what +
                     " options (see the message above)");
  }
}

// Writes fields.ToYaml() to `file` atomically. With a `command` ("track"),
// the first line is OptionsUsedMark(command): an options_used.yaml written
// beside a command's output, in a folder the user chose, carries the mark
// that lets a later run replace it as hmc's own (docs/reliability.md, "Side
// files"); a YAML comment, so the file still loads as a --config.
void WriteOptionsUsed(const OptionFields& fields,
                      const std::filesystem::path& file,
                      const std::string& command = "");

// "# options used by hmc COMMAND (docs/formats.md)".
std::string OptionsUsedMark(const std::string& command);

}  // namespace hmc
