// `hmc`: one binary, one subcommand per stage or tool (like `colmap <cmd>`).
#include <cstdio>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "apps/command.h"
#include "core/allocator.h"
#include "core/error.h"
#include "core/logging.h"
#include "core/parallel.h"

int main(int argc, char** argv) {
  using namespace hmc;
  KeepFreedMemoryForReuse();
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
      ->check(CLI::Range(0, 4096));
  app.set_version_flag("--version", "hmc " HMC_VERSION_TEXT, "The version of hmc");
  app.footer("Flags are spelt with underscores (--noise_mm); hyphens work as well (--noise-mm).");

  CommandRun run;
  AddRegisteredCommands(&app, &run);

  try {
    ParseCommandLine(&app, std::vector<std::string>(argv + 1, argv + argc));
  } catch (const InputError& e) {  // an unknown flag
    std::fprintf(stderr, "hmc: error: %s\n", e.what());
    return 2;
  } catch (const CLI::CallForVersion& e) {
    std::printf("%s\n", e.what());
    return 0;
  } catch (const CLI::ParseError& e) {
    // A word where a command belongs that names none: say so, rather than
    // CLI11's "A subcommand is required".
    const CLI::App* level = &app;
    std::string path = "hmc";
    for (int i = 1; i < argc && level->get_require_subcommand_min() > 0; ++i) {
      const std::string word = argv[i];
      if (word.empty() || word[0] == '-') continue;
      const CLI::App* next = nullptr;
      for (const CLI::App* sub : level->get_subcommands({})) {
        if (sub->get_name() == word) next = sub;
      }
      if (next == nullptr) {
        std::fprintf(stderr, "hmc: error: unknown command '%s %s' (%s --help lists them)\n",
                     path.c_str(), word.c_str(), path.c_str());
        return 2;
      }
      level = next;
      path += " " + word;
    }
    // Command-line errors exit 2, like input errors; --help exits 0.
    return app.exit(e) == 0 ? 0 : 2;
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
