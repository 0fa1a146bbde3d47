// --config YAML through the options registry (core/options.h): one field of
// every value type, grouped and not.
#include "core/options.h"
#include "fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = hmc::fuzz::WriteInput(data, size, "config.yaml");
  double number = 0;
  int integer = 0;
  bool flag = false;
  std::string text;
  std::vector<double> numbers;
  std::vector<std::string> texts;
  hmc::OptionFields fields;
  fields.Add("method", &text, "");
  fields.SetGroup("solve");
  fields.Add("tolerance_mm", &number, "");
  fields.Add("window", &integer, "");
  fields.Add("enabled", &flag, "");
  fields.Add("noise_mm", &numbers, "");
  fields.Add("names", &texts, "");
  fields.SetGroup("");
  return hmc::fuzz::Refusable([&] {
    fields.LoadYamlFile(path);
    fields.ToYaml();
  });
}
