// actor.yaml (core/actor_io.h: ParseActorYaml).
#include "core/actor_io.h"
#include "fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return hmc::fuzz::Refusable(
      [&] { hmc::actor_io::ParseActorYaml(hmc::fuzz::Text(data, size), "actor.yaml"); });
}
