// The lgi index cache file (docs/formats.md, "lgi_index.bin"): the shape
// index, then the natural-neighbour weights, as LoadLgiCache reads them.
#include <sstream>

#include "blending/natural_neighbour.h"
#include "fuzz/fuzz_util.h"
#include "indexing/shape_index.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  std::istringstream in(hmc::fuzz::Text(data, size));
  return hmc::fuzz::Refusable([&] {
    hmc::ShapeIndex::Read(in);
    hmc::NaturalNeighbourWeights::Read(in);
  });
}
