// markers.csv against the fixture actor's neutral (core/actor_io.h:
// ParseMarkersCsv; HMC_SOURCE_DIR or the working folder locates
// tests/fixtures/dcc_actor).
#include <cstdlib>

#include "core/actor_io.h"
#include "core/file_util.h"
#include "core/obj_io.h"
#include "fuzz/fuzz_util.h"

namespace {

struct Neutral {
  std::filesystem::path file;
  hmc::TriMesh mesh;
  hmc::ObjPolygons polygons;
};

const Neutral& GetNeutral() {
  static const Neutral neutral = [] {
    const char* root = std::getenv("HMC_SOURCE_DIR");
    Neutral n;
    n.file = std::filesystem::path(root ? root : ".") / "tests/fixtures/dcc_actor/neutral.obj";
    n.mesh = hmc::ParseObj(hmc::ReadFile(n.file), n.file, {}, &n.polygons);
    return n;
  }();
  return neutral;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const Neutral& n = GetNeutral();
  return hmc::fuzz::Refusable([&] {
    hmc::actor_io::ParseMarkersCsv(hmc::fuzz::Text(data, size), "markers.csv", n.mesh,
                                   n.polygons, n.file);
  });
}
