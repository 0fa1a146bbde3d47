// The command line as every command sees it (apps/command.h): each flag of
// each command parses in both spellings, the registered names are the house
// spelling, and an unknown flag is named with the nearest known one.
#include "apps/command.h"

#include <algorithm>
#include <functional>
#include <string>
#include <vector>

#include <gtest/gtest.h>

namespace hmc {
namespace {

struct Command {
  std::vector<std::string> words;  // {"actor", "frames"}
  const CLI::App* app;
};

// Every runnable command of `app` (the leaves of the command tree).
std::vector<Command> Commands(const CLI::App* app, std::vector<std::string> words = {}) {
  std::vector<Command> out;
  const auto subs = app->get_subcommands([](const CLI::App*) { return true; });
  if (subs.empty() && !words.empty()) out.push_back({words, app});
  for (const CLI::App* sub : subs) {
    std::vector<std::string> w = words;
    w.push_back(sub->get_name());
    const auto more = Commands(sub, w);
    out.insert(out.end(), more.begin(), more.end());
  }
  return out;
}

std::string Hyphenated(std::string flag) {
  std::replace(flag.begin() + 2, flag.end(), '_', '-');
  return flag;
}

// Parses `hmc <words> <flag> [1]` into a fresh tree of the commands; true
// unless the flag was refused as unknown (other errors, such as a missing
// required flag or a value that is no file, are not this test's).
bool FlagIsKnown(const Command& command, const std::string& flag, bool takes_value) {
  CommandTree tree;
  std::vector<std::string> args = command.words;
  args.push_back(flag);
  if (takes_value) args.push_back("1");
  try {
    ParseCommandLine(&tree.app, args);
  } catch (const InputError& e) {
    ADD_FAILURE() << e.what();
    return false;
  } catch (const CLI::ExtrasError& e) {
    ADD_FAILURE() << e.what();
    return false;
  } catch (const CLI::ParseError&) {
  }
  return true;
}

TEST(CommandTest, EveryFlagOfEveryCommandParsesWithUnderscoresAndWithHyphens) {
  CommandTree tree;
  const std::vector<Command> commands = Commands(&tree.app);
  ASSERT_GE(commands.size(), 15u);
  int flags = 0, hyphenated = 0;
  for (const Command& command : commands) {
    for (const CLI::Option* option : command.app->get_options()) {
      const bool takes_value = option->get_expected_min() > 0;
      for (const std::string& name : option->get_lnames()) {
        const std::string flag = "--" + name;
        // The house spelling: no hyphen in a registered name.
        EXPECT_EQ(name.find('-'), std::string::npos) << flag;
        EXPECT_TRUE(FlagIsKnown(command, flag, takes_value)) << flag;
        if (flag.find('_') != std::string::npos) {
          EXPECT_TRUE(FlagIsKnown(command, Hyphenated(flag), takes_value)) << Hyphenated(flag);
          ++hyphenated;
        }
        ++flags;
      }
    }
  }
  EXPECT_GE(flags, 200);
  EXPECT_GE(hyphenated, 100);
}

TEST(CommandTest, OnlyTheFlagNameIsRespelt) {
  EXPECT_EQ(CanonicalFlag("--noise-mm"), "--noise_mm");
  EXPECT_EQ(CanonicalFlag("--noise-mm=a-b"), "--noise_mm=a-b");
  EXPECT_EQ(CanonicalFlag("--index.min-volume"), "--index.min_volume");
  EXPECT_EQ(CanonicalFlag("-v"), "-v");
  EXPECT_EQ(CanonicalFlag("-1.5"), "-1.5");
  EXPECT_EQ(CanonicalFlag("a-b"), "a-b");
}

TEST(CommandTest, AnUnknownFlagIsNamedWithTheNearestFlagOfItsCommand) {
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{"run", "--fsp", "60"}, "did you mean --fps?"},
      {{"solve", "--acter", "x"}, "did you mean --actor?"},
      {{"actor", "frames", "--noise-nm", "1"}, "did you mean --noise_mm?"},
      {{"track", "--reference_frmae", "3"}, "did you mean --reference_frame?"},
  };
  for (const auto& [args, expected] : cases) {
    CommandTree tree;
    try {
      ParseCommandLine(&tree.app, args);
      ADD_FAILURE() << args[1] << " parsed";
    } catch (const InputError& e) {
      const std::string message = e.what();
      EXPECT_NE(message.find("unknown option"), std::string::npos) << message;
      EXPECT_NE(message.find(expected), std::string::npos) << message;
    }
  }
  // Nothing near: no suggestion, still named.
  CommandTree tree;
  try {
    ParseCommandLine(&tree.app, {"solve", "--completely_unrelated_words", "1"});
    ADD_FAILURE() << "parsed";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("--completely_unrelated_words"), std::string::npos);
    EXPECT_EQ(std::string(e.what()).find("did you mean"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace hmc
