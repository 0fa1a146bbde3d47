// OBJ (core/obj_io.h: ParseObj, with the polygons markers.csv refers to).
#include "core/obj_io.h"
#include "fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return hmc::fuzz::Refusable([&] {
    hmc::ObjPolygons polygons;
    hmc::ParseObj(hmc::fuzz::Text(data, size), "fuzz.obj", {}, &polygons);
  });
}
