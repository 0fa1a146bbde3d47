// One field registry per options struct drives the YAML config, the CLI
// flags and the `options_used.yaml` written next to each output
// (STYLE.md "Stage contract"). Defaults live only in the options header,
// as default member initialisers; the registry only points at the fields.
//
// An options struct provides
//   void Register(OptionFields* fields);   // fields->Add("name", &name_, "help (unit)")
//   bool Check() const;                     // logs the offending option
// Field names are snake_case; a group ("index", "blend") nests them in YAML
// (`index: {min_volume: ...}`) and prefixes the CLI flag (`--index.min_volume`).
#pragma once

#include <filesystem>
#include <functional>
#include <string>
#include <variant>
#include <vector>

#include <yaml-cpp/yaml.h>

#include "core/error.h"

namespace hmc {

class OptionFields {
 public:
  using Pointer = std::variant<double*, int*, bool*, std::string*>;
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

// Throws InputError if options.Check() fails (Check logs the reason): how a
// stage's entry point refuses invalid options.
template <typename Options>
void RequireValid(const Options& options, const char* what) {
  if (!options.Check()) {
    throw InputError(std::string("invalid ") + what +
                     " options (see the message above)");
  }
}

// Writes fields.ToYaml() to `file` atomically.
void WriteOptionsUsed(const OptionFields& fields,
                      const std::filesystem::path& file);

}  // namespace hmc
