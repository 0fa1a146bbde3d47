// .usda mesh sequences (core/mesh_sequence.h: ReadMeshSequence).
#include "core/mesh_sequence.h"
#include "fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = hmc::fuzz::WriteInput(data, size, "fuzz.usda");
  return hmc::fuzz::Refusable([&] { hmc::ReadMeshSequence(path); });
}
