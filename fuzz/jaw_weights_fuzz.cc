// The jaw weights file, read by LoadActor from a copy of the fixture actor
// (tests/fixtures/dcc_actor) whose jaw_weights.txt is the input.
#include <cstdlib>

#include "core/actor.h"
#include "fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  namespace fs = std::filesystem;
  static const fs::path package = [] {
    const char* root = std::getenv("HMC_SOURCE_DIR");
    const fs::path dir = hmc::fuzz::ScratchDir() / "actor";
    fs::remove_all(dir);
    fs::copy(fs::path(root ? root : ".") / "tests/fixtures/dcc_actor", dir,
             fs::copy_options::recursive);
    return dir;
  }();
  hmc::fuzz::WriteInput(data, size, "actor/jaw_weights.txt");
  return hmc::fuzz::Refusable([&] { hmc::LoadActor(package); });
}
