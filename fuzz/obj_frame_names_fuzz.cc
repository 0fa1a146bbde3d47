// OBJ-folder frame names (frame_<digits>.obj; core/mesh_sequence_obj.cc):
// a name that parses must give back a frame whose own name parses to it.
#include <optional>

#include "core/error.h"
#include "fuzz/fuzz_util.h"

namespace hmc::sequence_io {
std::string ObjFrameName(int frame);
std::optional<int> ObjFrameNumber(const std::string& name);
}  // namespace hmc::sequence_io

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace hmc::sequence_io;
  const std::optional<int> frame = ObjFrameNumber(hmc::fuzz::Text(data, size));
  if (frame && ObjFrameNumber(ObjFrameName(*frame)) != frame) std::abort();
  return 0;
}
