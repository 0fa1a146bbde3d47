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

// A fresh `hmc` app with every registered command, as RunCommandLine
// parses into; `run` is what the parsed command would run.
struct CommandTree {
  CommandTree() {
    app.require_subcommand(1);
    AddRegisteredCommands(&app, &run);
  }
  CLI::App app{"hmc", "hmc"};
  CommandRun run;
};

// Flags are spelt with underscores (`--noise_mm`, `--reference_frame`):
// the house spelling, the one --help shows. Every flag of every command is
// also accepted with hyphens (`--noise-mm`): ParseCommandLine rewrites a
// long flag's name to the underscore form before CLI11 sees it, so no alias
// is written per flag.
std::string CanonicalFlag(const std::string& token);

// The long flags (`--name`) `app` and the apps above it accept.
std::vector<std::string> KnownFlags(const CLI::App* app);

// Parses `args` (without the program name) into `app`: hyphenated flags
// become their underscore form, and a flag that neither `app` nor the
// command the words name knows throws InputError "unknown option --fsp; did
// you mean --fps?" (nearest by edit distance among that command's flags)
// before anything else is checked. Other errors are CLI11's ParseError.
void ParseCommandLine(CLI::App* app, const std::vector<std::string>& args);

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
  ~OptionBinding();
  OptionBinding(const OptionBinding&) = delete;
  OptionBinding& operator=(const OptionBinding&) = delete;
  void Apply();
  // The options' own Check() (BindOptions sets it); CheckCommandConfig
  // runs it after loading a config section.
  void SetCheck(std::function<bool()> check) { check_ = std::move(check); }
  bool Check() const { return !check_ || check_(); }
  // Loads a mapping of option values (`section` of `file`) into the fields.
  void LoadSection(const YAML::Node& section, const std::filesystem::path& file) {
    fields_.LoadYaml(section, file);
  }
  const OptionFields& fields() const { return fields_; }
  const std::string& config_file() const { return config_file_; }

 private:
  OptionFields fields_;
  std::string config_section_;
  std::string config_file_;
  std::vector<std::pair<const OptionFields::Field*, CLI::Option*>> flags_;
  std::vector<std::unique_ptr<std::string>> values_;
  std::function<bool()> check_;
  const CLI::App* app_;
};

// Checks `section` of the config `file` as command `words` ({"solve"})
// would read it from its --config, without running anything: unknown keys,
// types, ranges and the options' own Check(). Throws InputError naming
// `file` (and the line, for what a key's line can tell). How `hmc run`
// checks every stage's section before the first stage runs.
void CheckCommandConfig(const std::vector<std::string>& words, const YAML::Node& section,
                        const std::filesystem::path& file);

// Registers `options`' fields and binds them to `app`. `options` must outlive
// the returned binding (hold both in the command's run closure).
template <typename Options>
std::shared_ptr<OptionBinding> BindOptions(CLI::App* app, Options* options) {
  OptionFields fields;
  options->Register(&fields);
  auto binding = std::make_shared<OptionBinding>(app, std::move(fields));
  binding->SetCheck([options] { return options->Check(); });
  return binding;
}

}  // namespace hmc

#define HMC_COMMAND(id, group, name, help)                                 \
  static ::hmc::CommandRun HmcCommandSetup_##id(CLI::App* app);            \
  [[maybe_unused]] static const bool kHmcCommandRegistered_##id =          \
      ::hmc::RegisterCommand(group, name, help, &HmcCommandSetup_##id);    \
  static ::hmc::CommandRun HmcCommandSetup_##id(CLI::App* app)
