// calibration.yaml (core/calibration.h: ReadCalibration, OpenCV FileStorage).
#include "core/calibration.h"
#include "fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = hmc::fuzz::WriteInput(data, size, "calibration.yaml");
  return hmc::fuzz::Refusable([&] { hmc::ReadCalibration(path); });
}
