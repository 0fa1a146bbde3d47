// Kalibr camchain YAML (core/kalibr.h: ReadKalibrCamchain).
#include "core/kalibr.h"
#include "fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = hmc::fuzz::WriteInput(data, size, "camchain.yaml");
  return hmc::fuzz::Refusable([&] { hmc::ReadKalibrCamchain(path); });
}
