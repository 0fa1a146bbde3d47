// rays.csv (triangulation/triangulate.h: ReadRaysCsv).
#include "fuzz/fuzz_util.h"
#include "triangulation/triangulate.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = hmc::fuzz::WriteInput(data, size, "rays.csv");
  return hmc::fuzz::Refusable([&] { hmc::ReadRaysCsv(path); });
}
