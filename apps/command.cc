#include "apps/command.h"

#include <algorithm>
#include <fstream>
#include <map>
#include <vector>

#include <fmt/ranges.h>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "core/error.h"
#include "core/file_util.h"
#include "core/text.h"

namespace hmc {
namespace {

namespace fs = std::filesystem;

struct Registered {
  const char* group;
  const char* name;
  const char* help;
  CommandSetup setup;
};

std::vector<Registered>& Registry() {
  static std::vector<Registered> registry;
  return registry;
}

// The binding of each command's app, for CheckCommandConfig.
std::map<const CLI::App*, OptionBinding*>& Bindings() {
  static std::map<const CLI::App*, OptionBinding*> bindings;
  return bindings;
}

const std::map<std::string, std::string>& GroupHelp() {
  static const std::map<std::string, std::string> help = {
      {"actor", "Actor packages: synthesize, check, ground-truth frames, preview"},
      {"synth", "Synthetic footage with exact ground truth"},
      {"debug", "Pictures of intermediate results, for debugging one stage"},
  };
  return help;
}

}  // namespace

bool RegisterCommand(const char* group, const char* name, const char* help,
                     CommandSetup setup) {
  Registry().push_back({group, name, help, std::move(setup)});
  return true;
}

void AddRegisteredCommands(CLI::App* app, CommandRun* run) {
  std::map<std::string, CLI::App*> groups;
  for (auto& command : Registry()) {
    CLI::App* parent = app;
    if (command.group[0] != '\0') {
      auto it = groups.find(command.group);
      if (it == groups.end()) {
        const auto help = GroupHelp().find(command.group);
        CLI::App* group = app->add_subcommand(
            command.group,
            help == GroupHelp().end() ? std::string() : help->second);
        group->require_subcommand(1);
        it = groups.emplace(command.group, group).first;
      }
      parent = it->second;
    }
    CLI::App* sub = parent->add_subcommand(command.name, command.help);
    CommandRun command_run = command.setup(sub);
    sub->callback([run, command_run] { *run = command_run; });
  }
}

namespace {

// hmc's commands by their full names ("track", "synth shot").
std::vector<std::string> CommandNames() {
  std::vector<std::string> names;
  for (const Registered& command : Registry()) {
    const std::string group = command.group;
    names.push_back(group.empty() ? command.name : group + " " + command.name);
  }
  return names;
}

// The hmc command whose mark the side file `side.path` carries (SideFile in
// command.h), "" when it carries none.
std::string SideFileWriter(const OutputFlag& side) {
  std::error_code ec;
  if (!fs::is_regular_file(side.path, ec)) return "";
  const std::vector<std::string> names = CommandNames();
  if (side.path.extension() == ".json") {
    std::string text;
    try {
      text = ReadFile(side.path);
    } catch (const InputError&) {
      return "";
    }
    const nlohmann::json json = nlohmann::json::parse(text, nullptr, false);
    if (!json.is_object() || !json.contains("stage") || !json["stage"].is_string()) return "";
    const std::string stage = json["stage"].get<std::string>();
    return std::find(names.begin(), names.end(), stage) != names.end() ? stage : "";
  }
  std::ifstream in(side.path);
  std::string first;
  std::getline(in, first);
  if (!side.header.empty()) return first == side.header ? side.side_of : "";
  for (const std::string& name : names) {
    if (first == OptionsUsedMark(name)) return name;
  }
  return "";
}

void CheckSideFile(const OutputFlag& side) {
  std::error_code ec;
  if (!fs::exists(fs::symlink_status(side.path, ec))) return;
  const std::string writer = SideFileWriter(side);
  if (writer.empty()) {
    ThrowInputError(side.path, 0,
                    "{}: a file hmc did not write (it carries no mark of an hmc command); hmc {} "
                    "would replace it, so it stops here and leaves it: move the file, or give "
                    "--out in another folder",
                    side.flag, side.side_of);
  }
  if (writer != side.side_of) {
    spdlog::warn("{}: replaces the {} that hmc {} wrote", side.path.string(),
                 side.path.filename().string(), writer);
  }
}

}  // namespace

OutputFlag SideFile(const fs::path& path, const std::string& command, const std::string& header) {
  return {path, path.filename().string() + " beside --out", false, command, header};
}

void PrepareOutputPaths(std::initializer_list<OutputFlag> outputs,
                        std::initializer_list<InputPath> inputs) {
  const std::vector<InputPath> in(inputs);
  for (const OutputFlag& o : outputs) {
    if (o.path.empty()) continue;
    PrepareOutputPath(o.path, o.flag, o.folder, in);
    if (!o.side_of.empty()) CheckSideFile(o);
  }
}

std::string CanonicalFlag(const std::string& token) {
  if (token.size() <= 2 || token.compare(0, 2, "--") != 0) return token;
  const size_t end = std::min(token.find('='), token.size());
  std::string out = token;
  std::replace(out.begin() + 2, out.begin() + static_cast<std::ptrdiff_t>(end), '-', '_');
  return out;
}

std::vector<std::string> KnownFlags(const CLI::App* app) {
  std::vector<std::string> flags;
  for (; app != nullptr; app = app->get_parent()) {
    for (const CLI::Option* option : app->get_options()) {
      for (const std::string& name : option->get_lnames()) flags.push_back("--" + name);
    }
  }
  return flags;
}

void ParseCommandLine(CLI::App* app, const std::vector<std::string>& args) {
  std::vector<std::string> canonical;
  bool rest_positional = false;  // after a bare "--" nothing is a flag
  for (const std::string& a : args) {
    rest_positional = rest_positional || a == "--";
    canonical.push_back(rest_positional ? a : CanonicalFlag(a));
  }
  // Walk the command words as CLI11 will, checking each flag against the
  // flags of the command named so far (and of the apps above it).
  const CLI::App* level = app;
  for (const std::string& a : canonical) {
    if (a == "--") break;
    if (a.compare(0, 2, "--") == 0) {
      const std::string name = a.substr(0, a.find('='));
      const std::vector<std::string> known = KnownFlags(level);
      if (std::find(known.begin(), known.end(), name) != known.end()) continue;
      const std::string near = NearestWord(name, known, std::max<int>(2, name.size() / 4));
      throw InputError(fmt::format("unknown option {}{} ({} --help lists them)", name,
                                   near.empty() ? "" : "; did you mean " + near + "?",
                                   level == app ? "hmc" : "hmc " + level->get_name()));
    }
    if (a.empty() || a[0] == '-' || level->get_require_subcommand_min() == 0) continue;
    const CLI::App* next = nullptr;
    for (const CLI::App* sub : level->get_subcommands({})) {
      if (sub->get_name() == a) next = sub;
    }
    if (next == nullptr) break;  // not a command: the caller's message
    level = next;
  }
  std::vector<std::string> reversed(canonical.rbegin(), canonical.rend());  // CLI11's order
  app->parse(reversed);
}

int RunCommandLine(const std::vector<std::string>& args) {
  CommandTree tree;
  try {
    ParseCommandLine(&tree.app, args);
  } catch (const CLI::ParseError& e) {
    std::string line;
    for (const std::string& a : args) line += " " + a;
    throw InputError(fmt::format("hmc{}: {}", line, e.what()));
  }
  if (!tree.run) throw InputError("no command to run");
  return tree.run();
}

OptionBinding::~OptionBinding() { Bindings().erase(app_); }

void CheckCommandConfig(const std::vector<std::string>& words, const YAML::Node& section,
                        const std::filesystem::path& file) {
  CommandTree tree;
  const CLI::App* command = &tree.app;
  for (const std::string& word : words) command = command->get_subcommand(word);
  const auto it = Bindings().find(command);
  HMC_CHECK_MSG(it != Bindings().end(), "hmc " + command->get_name() + " binds no options");
  it->second->LoadSection(section, file);
  // Named as the run config names it: the stage's section, then the key.
  const std::string range =
      it->second->fields().RangeError(fmt::format("{}.", fmt::join(words, ".")));
  if (!range.empty()) throw InputError(range);
  if (!it->second->Check()) {
    ThrowInputError(file, section.Mark().line + 1, "invalid {} options (see the message above)",
                    fmt::format("{}", fmt::join(words, " ")));
  }
}

OptionBinding::OptionBinding(CLI::App* app, OptionFields fields, std::string config_section)
    : fields_(std::move(fields)), config_section_(std::move(config_section)), app_(app) {
  Bindings()[app] = this;
  app->add_option("--config", config_file_,
                  "YAML file of option values (defaults: configs/); flags on "
                  "the command line override it")
      ->check(CLI::ExistingFile);
  for (const auto& field : fields_.fields()) {
    values_.push_back(std::make_unique<std::string>());
    CLI::Option* flag =
        app->add_option("--" + field.name, *values_.back(),
                        OptionFields::RangeText(field).empty()
                            ? field.help
                            : field.help + " [" + OptionFields::RangeText(field) + "]")
            ->default_str(fields_.ValueString(field))
            ->type_name(std::visit(
                [](auto* pointer) -> std::string {
                  using T = std::remove_pointer_t<decltype(pointer)>;
                  if constexpr (std::is_same_v<T, double>) return "NUMBER";
                  if constexpr (std::is_same_v<T, int>) return "INT";
                  if constexpr (std::is_same_v<T, bool>) return "BOOL";
                  if constexpr (std::is_same_v<T, std::vector<double>>) {
                    return "NUMBER,...";
                  }
                  if constexpr (std::is_same_v<T, std::vector<std::string>>) {
                    return "TEXT,...";
                  }
                  return "TEXT";
                },
                field.pointer))
            ->group("Options (also settable in --config)");
    flags_.emplace_back(&field, flag);
  }
}

void OptionBinding::Apply() {
  if (!config_file_.empty() && config_section_.empty()) fields_.LoadYamlFile(config_file_);
  if (!config_file_.empty() && !config_section_.empty()) {
    const YAML::Node root = hmc::LoadYamlFile(config_file_);
    if (root.IsMap() && root[config_section_]) {
      fields_.LoadYaml(root[config_section_], config_file_);
    }
  }
  for (size_t i = 0; i < flags_.size(); ++i) {
    if (flags_[i].second->count() > 0) {
      fields_.Set(flags_[i].first->name, *values_[i],
                  "--" + flags_[i].first->name);
    }
  }
}

}  // namespace hmc
