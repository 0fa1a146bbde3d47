// `hmc`: one binary, one subcommand per stage or tool (like `colmap <cmd>`).
#include <cstdio>

#include <CLI/CLI.hpp>

#include "apps/command.h"
#include "core/error.h"
#include "core/logging.h"
#include "core/parallel.h"

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

  CommandRun run;
  AddRegisteredCommands(&app, &run);

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
