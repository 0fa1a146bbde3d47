// `hmc`: one binary, one subcommand per stage or tool (like `colmap <cmd>`).
#include <cstdio>
#include <map>
#include <vector>

#include <CLI/CLI.hpp>

#include "apps/command.h"
#include "core/error.h"
#include "core/logging.h"
#include "core/parallel.h"

namespace hmc {
namespace {

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

}  // namespace hmc

int main(int argc, char** argv) {
  using namespace hmc;
  CLI::App app("hmc: facial performance capture from stereo helmet-camera "
               "footage,\nby local geometric indexing of a dataset of facial "
               "shapes.",
               "hmc");
  app.require_subcommand(1);
  app.fallthrough();
  int verbosity = 0;
  bool quiet = false;
  int threads = 0;
  app.add_flag("-v,--verbose", verbosity, "More detail (-v debug, -vv trace)");
  app.add_flag("-q,--quiet", quiet, "Only warnings and errors");
  app.add_option("--threads", threads, "Worker threads (0: all cores)")
      ->check(CLI::NonNegativeNumber);

  std::map<std::string, CLI::App*> groups;
  CommandRun run;
  for (auto& command : Registry()) {
    CLI::App* parent = &app;
    if (command.group[0] != '\0') {
      auto it = groups.find(command.group);
      if (it == groups.end()) {
        const auto help = GroupHelp().find(command.group);
        CLI::App* group = app.add_subcommand(
            command.group,
            help == GroupHelp().end() ? std::string() : help->second);
        group->require_subcommand(1);
        it = groups.emplace(command.group, group).first;
      }
      parent = it->second;
    }
    CLI::App* sub = parent->add_subcommand(command.name, command.help);
    CommandRun command_run = command.setup(sub);
    sub->callback([&run, command_run] { run = command_run; });
  }

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  InitLogging(quiet ? -1 : verbosity);
  ThreadLimit thread_limit(threads);
  try {
    return run ? run() : 1;
  } catch (const InputError& e) {
    std::fprintf(stderr, "hmc: error: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "hmc: error: %s\n", e.what());
    return 1;
  }
}
