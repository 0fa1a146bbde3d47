// One field registry per options struct drives the YAML config, the CLI
// flags and the `options_used.yaml` written next to each output
// (docs/ARCHITECTURE.md, "Contracts"). Defaults live only in the options header,
// as default member initialisers; the registry only points at the fields.
//
// An options struct provides
//   void Register(OptionFields* fields);   // fields->Add("name", &name_, "help (unit)")
//   bool Check() const;                     // logs the offending option
// and writes Check() with the CHECK_OPTION macros below (as COLMAP does):
//   bool Check() const {
//     CHECK_OPTION_GE(tolerance_mm, 0.0);
//     CHECK_OPTION_IN(fraction, 0.0, 1.0);
//     CHECK_OPTION(!methods.empty());
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
  };

  // Fields added after this call are named "<group>.<name>" ("" = no group).
  void SetGroup(std::string group) { group_ = std::move(group); }

  void Add(const std::string& name, double* field, std::string help);
  void Add(const std::string& name, int* field, std::string help);
  void Add(const std::string& name, bool* field, std::string help);
  void Add(const std::string& name, std::string* field, std::string help);
  void Add(const std::string& name, std::vector<double>* field,
           std::string help);
  void Add(const std::string& name, std::vector<std::string>* field,
           std::string help);

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
  void AddField(const std::string& name, Pointer pointer, std::string help);
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
