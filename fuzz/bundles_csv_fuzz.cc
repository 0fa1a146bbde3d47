// bundles.csv (core/frame_data.h: ReadBundlesCsv).
#include "core/frame_data.h"
#include "fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = hmc::fuzz::WriteInput(data, size, "bundles.csv");
  return hmc::fuzz::Refusable([&] { hmc::ReadBundlesCsv(path); });
}
