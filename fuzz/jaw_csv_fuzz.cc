// jaw.csv (core/frame_data.h: ReadJawCsv) and head_from_helmet.csv
// (ReadPosesCsv), both from the same bytes.
#include "core/frame_data.h"
#include "fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = hmc::fuzz::WriteInput(data, size, "jaw.csv");
  hmc::fuzz::Refusable([&] { hmc::ReadJawCsv(path); });
  return hmc::fuzz::Refusable([&] { hmc::ReadPosesCsv(path); });
}
