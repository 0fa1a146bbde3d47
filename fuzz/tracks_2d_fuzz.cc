// tracks_2d.csv and dots_2d.csv (core/tracks_2d.h), both from the same bytes.
#include "core/tracks_2d.h"
#include "fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = hmc::fuzz::WriteInput(data, size, "tracks_2d.csv");
  hmc::fuzz::Refusable([&] { hmc::ReadTracks2dCsv(path); });
  return hmc::fuzz::Refusable([&] { hmc::ReadDots2dCsv(path); });
}
