// Self-registering `hmc` commands. Each command lives in its own cmd_*.cc:
//
//   HMC_COMMAND(ActorSynth, "actor", "synth", "Write the synthetic actor") {
//     auto out = std::make_shared<std::string>();
//     app->add_option("--out", *out, "...")->required();
//     return [=] { ...; return 0; };
//   }
//
// `app` is the command's CLI11 sub-app; the body adds the command's flags
// and returns what runs after parsing. Group "" makes a top-level command.
#pragma once

#include <filesystem>
#include <functional>
#include <initializer_list>
#include <memory>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "core/error.h"
#include "core/file_util.h"
#include "core/options.h"

namespace hmc {

using CommandRun = std::function<int()>;
using CommandSetup = std::function<CommandRun(CLI::App* app)>;

bool RegisterCommand(const char* group, const char* name, const char* help,
                     CommandSetup setup);

// Adds every registered command (inside its group) to `app`; the command
// the parse selects stores what to run in *run (which must outlive `app`).
void AddRegisteredCommands(CLI::App* app, CommandRun* run);

// Runs the command line `hmc <args...>` (without global flags) in this
// process and returns its exit code; what the command throws passes
// through, a parse error becomes an InputError. `hmc run` chains the stages
// with it, so each stage runs exactly as its own command.
int RunCommandLine(const std::vector<std::string>& args);

// One output flag of a command, for PrepareOutputPaths.
struct OutputFlag {
  std::filesystem::path path;  // empty: the flag was not given, skipped
  std::string flag;            // "--out", named in the error
  bool folder = false;         // a folder output (else a file)
  // A side file (SideFile below) of this command ("track"); empty for an
  // output the user named.
  std::string side_of = "";
  std::string header = "";  // a side CSV's fixed header line: its mark
};

// A file a command names itself and writes beside --out, in a folder the
// user chose (summary.json, options_used.yaml, jaw_summary.json, rays.csv
// when --rays is not given): flag "NAME beside --out". It replaces only a
// file of that name that hmc wrote, known by its mark: a JSON object whose
// "stage" names an hmc command, an options_used.yaml whose first line is
// OptionsUsedMark (core/options.h), a CSV whose first line is `header`.
// Anything else there is the user's: refused before any work, naming it,
// and left as it was (docs/reliability.md, "Side files"). Replacing
// another command's side file is warned.
OutputFlag SideFile(const std::filesystem::path& path, const std::string& command,
                    const std::string& header = "");

// What every command that writes calls before it reads or computes
// anything (docs/reliability.md), so that a bad output path costs no work
// and replaces no earlier output: PrepareOutputPath (core/file_util.h)
// for each given flag, with the overlap check against the command's
// `inputs` (an output that is an input or lies in an input folder), and
// the ownership check of each side file (SideFile).
// Throws InputError naming the path and the flag.
void PrepareOutputPaths(std::initializer_list<OutputFlag> outputs,
                        std::initializer_list<InputPath> inputs = {});

// Adds `--config FILE` and one flag `--<field>` per registered option field
// to `app`. Apply() (call at run time) loads the config file, then the flags
// given on the command line on top of it. Unknown config keys are errors.
// With a `config_section`, the config file is a mapping of which only that
// key's value holds these options (other keys belong to others: the stage
// sections of `hmc run`'s config).
class OptionBinding {
 public:
  OptionBinding(CLI::App* app, OptionFields fields, std::string config_section = "");
  void Apply();
  const OptionFields& fields() const { return fields_; }
  const std::string& config_file() const { return config_file_; }

 private:
  OptionFields fields_;
  std::string config_section_;
  std::string config_file_;
  std::vector<std::pair<const OptionFields::Field*, CLI::Option*>> flags_;
  std::vector<std::unique_ptr<std::string>> values_;
};

// Registers `options`' fields and binds them to `app`. `options` must outlive
// the returned binding (hold both in the command's run closure).
template <typename Options>
std::shared_ptr<OptionBinding> BindOptions(CLI::App* app, Options* options) {
  OptionFields fields;
  options->Register(&fields);
  return std::make_shared<OptionBinding>(app, std::move(fields));
}

}  // namespace hmc

#define HMC_COMMAND(id, group, name, help)                                 \
  static ::hmc::CommandRun HmcCommandSetup_##id(CLI::App* app);            \
  [[maybe_unused]] static const bool kHmcCommandRegistered_##id =          \
      ::hmc::RegisterCommand(group, name, help, &HmcCommandSetup_##id);    \
  static ::hmc::CommandRun HmcCommandSetup_##id(CLI::App* app)
