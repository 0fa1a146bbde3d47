#include "core/options.h"

#include <filesystem>
#include <fstream>
#include <limits>
#include <vector>

#include <gtest/gtest.h>

#include "core/error.h"

namespace hmc {
namespace {

struct ExampleOptions {
  double threshold_mm = 0.25;  // a number
  int count = 3;               // an integer
  bool enabled = true;         // a switch
  std::string mode = "uv";     // a word
  double grid_cell_mm = 2.0;   // in a group
  std::vector<double> levels = {0, 0.5};  // a list of numbers, any range

  void Register(OptionFields* fields) {
    fields->Add("threshold_mm", &threshold_mm, "threshold (mm)").Above(0).AtMost(10);
    fields->Add("count", &count, "count").In(1, 5);
    fields->Add("enabled", &enabled, "switch");
    fields->Add("mode", &mode, "mode").OneOf({"uv", "xyz"});
    fields->SetGroup("grid");
    fields->Add("cell_mm", &grid_cell_mm, "cell size (mm)").AtLeast(0.5);
    fields->SetGroup("");
    fields->Add("levels", &levels, "levels");
  }
  bool Check() const {
    CHECK_OPTION_LIMITS();
    CHECK_OPTION(mode == "uv" || count >= 2);  // what involves two fields
    return true;
  }
};

std::filesystem::path TempFile(const std::string& name,
                               const std::string& text) {
  const auto path = std::filesystem::temp_directory_path() / name;
  std::ofstream(path) << text;
  return path;
}

TEST(OptionsTest, YamlSetsNestedFields) {
  ExampleOptions options;
  OptionFields fields;
  options.Register(&fields);
  fields.LoadYaml(YAML::Load("threshold_mm: 0.5\ncount: 7\nenabled: false\n"
                             "mode: geodesic\ngrid: {cell_mm: 1.5}\n"),
                  "example.yaml");
  EXPECT_EQ(options.threshold_mm, 0.5);
  EXPECT_EQ(options.count, 7);
  EXPECT_FALSE(options.enabled);
  EXPECT_EQ(options.mode, "geodesic");
  EXPECT_EQ(options.grid_cell_mm, 1.5);
}

TEST(OptionsTest, UnknownKeyNamesFileAndLine) {
  ExampleOptions options;
  OptionFields fields;
  options.Register(&fields);
  const auto path = TempFile("hmc_options_unknown.yaml",
                             "count: 2\n\ngrid:\n  cel_mm: 1\n");
  try {
    fields.LoadYamlFile(path);
    FAIL() << "unknown key accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), path);
    EXPECT_EQ(e.line(), 4);
    EXPECT_NE(std::string(e.what()).find("grid.cel_mm"), std::string::npos);
  }
  EXPECT_EQ(options.grid_cell_mm, 2.0);
}

TEST(OptionsTest, WrongTypeAndNonFiniteRefused) {
  ExampleOptions options;
  OptionFields fields;
  options.Register(&fields);
  EXPECT_THROW(fields.LoadYaml(YAML::Load("count: 2.5"), "a.yaml"), InputError);
  EXPECT_THROW(fields.LoadYaml(YAML::Load("threshold_mm: .nan"), "a.yaml"),
               InputError);
  EXPECT_THROW(fields.LoadYaml(YAML::Load("enabled: maybe"), "a.yaml"),
               InputError);
  EXPECT_THROW(fields.Set("count", "x", "--count"), InputError);
  EXPECT_THROW(fields.Set("nope", "1", "--nope"), InputError);
}

TEST(OptionsTest, CommandLineTextOverrides) {
  ExampleOptions options;
  OptionFields fields;
  options.Register(&fields);
  fields.Set("grid.cell_mm", "0.75", "--grid.cell_mm");
  fields.Set("mode", "123", "--mode");  // Strings stay verbatim.
  EXPECT_EQ(options.grid_cell_mm, 0.75);
  EXPECT_EQ(options.mode, "123");
}

TEST(OptionsTest, ToYamlRoundTripsEveryField) {
  ExampleOptions written;
  written.threshold_mm = 0.1 + 0.2;  // Not exactly representable in decimal.
  written.count = -4;
  written.enabled = false;
  written.mode = "geodesic";
  written.grid_cell_mm = 1.0 / 3.0;
  OptionFields out;
  written.Register(&out);
  const std::string text = YAML::Dump(out.ToYaml());

  ExampleOptions read;
  OptionFields in;
  read.Register(&in);
  in.LoadYaml(YAML::Load(text), "options_used.yaml");
  EXPECT_EQ(read.threshold_mm, written.threshold_mm);
  EXPECT_EQ(read.count, written.count);
  EXPECT_EQ(read.enabled, written.enabled);
  EXPECT_EQ(read.mode, written.mode);
  EXPECT_EQ(read.grid_cell_mm, written.grid_cell_mm);
}

// Issue 52: the range is declared with the field, and the check names
// where the value came from (the config's file and line, or the flag).
TEST(OptionsTest, DeclaredRangesAreCheckedAndNameWhereTheValueCameFrom) {
  EXPECT_TRUE(ExampleOptions().Check());
  // Each field just outside its range (and just inside: still valid).
  const std::vector<std::pair<std::string, bool>> cases = {
      {"threshold_mm: 0", false},    {"threshold_mm: 1e-9", true}, {"threshold_mm: 10", true},
      {"threshold_mm: 10.01", false}, {"count: 0", false},          {"count: 5", true},
      {"count: 6", false},           {"mode: xyz", true},          {"mode: xy", false},
      {"grid: {cell_mm: 0.49}", false}};
  for (const auto& [text, valid] : cases) {
    ExampleOptions options;
    OptionFields fields;
    options.Register(&fields);
    const auto file = TempFile("hmc_options_range.yaml", "enabled: true\n" + text + "\n");
    fields.LoadYamlFile(file);
    EXPECT_EQ(options.Check(), valid) << text;
    const std::string error = fields.RangeError();
    EXPECT_EQ(error.empty(), valid) << text;
    if (!valid) {
      EXPECT_NE(error.find("hmc_options_range.yaml:2"), std::string::npos) << error;
    }
  }
  ExampleOptions options;
  OptionFields fields;
  options.Register(&fields);
  fields.Set("count", "9", "--count");
  EXPECT_NE(fields.RangeError().find("--count: option 'count' = 9 must be in [1, 5]"),
            std::string::npos)
      << fields.RangeError();
  // A cross-field condition stays in Check().
  options.count = 1;
  options.mode = "xyz";
  EXPECT_TRUE(fields.RangeError().empty());
  EXPECT_FALSE(options.Check());
}

// Numbers set in code (a config or a flag cannot give them) must be finite,
// with or without a declared range: what a Check() once wrote per field.
TEST(OptionsTest, NonFiniteNumbersFailTheRangeCheck) {
  const double inf = std::numeric_limits<double>::infinity();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (const double bad : {inf, -inf, nan}) {
    ExampleOptions in_range_only;  // AtLeast(0.5) alone would take +inf
    in_range_only.grid_cell_mm = bad;
    EXPECT_FALSE(in_range_only.Check()) << bad;
    ExampleOptions no_range;
    no_range.levels = {0, bad};
    EXPECT_FALSE(no_range.Check()) << bad;
    OptionFields fields;
    no_range.Register(&fields);
    EXPECT_NE(fields.RangeError().find("option 'levels' = 0,"), std::string::npos)
        << fields.RangeError();
    EXPECT_NE(fields.RangeError().find(": item "), std::string::npos) << fields.RangeError();
    EXPECT_NE(fields.RangeError().find("must be finite"), std::string::npos)
        << fields.RangeError();
  }
  ExampleOptions finite;
  finite.levels = {-1e300, 1e300};
  EXPECT_TRUE(finite.Check());
}

// A list out of range names its first item that is (issue 52: `--methods
// lgi,rbf` said which method was unknown before the check was declared).
TEST(OptionsTest, AListNamesItsFirstItemOutOfRange) {
  std::vector<std::string> kinds = {"a", "c", "d"};
  std::vector<double> levels = {0.5, 2, 3};
  OptionFields fields;
  fields.Add("kinds", &kinds, "kinds").OneOf({"a", "b"});
  fields.Add("levels", &levels, "levels").In(0, 1);
  EXPECT_NE(fields.RangeError().find("option 'kinds' = a,c,d: item 'c' must be one of a, b"),
            std::string::npos)
      << fields.RangeError();
  kinds = {"b", "a"};
  EXPECT_NE(fields.RangeError().find("option 'levels' = 0.5,2,3: item 2 must be in [0, 1]"),
            std::string::npos)
      << fields.RangeError();
  levels = {1, 0};
  EXPECT_TRUE(fields.RangeError().empty()) << fields.RangeError();
}

}  // namespace
}  // namespace hmc
