// The painted-marker layout of the synthetic actor: ~155 dots placed the way
// HMC make-up artists paint them -- rows on the forehead, along the brows,
// rings around the eyes and lips (densest there), a grid on each cheek, the
// nasolabial line, chin and jaw line. Names are region + index
// ("mouth_upper_03", "cheek_l_07"); tags are the region plus `stable`
// (upper forehead, temples, nose bridge: points that barely move, used by
// stabilization) and `jaw` (chin and jaw line, used for the jaw solve).
#pragma once

#include <cstdint>
#include <vector>

#include "core/actor.h"
#include "synth/face_mesh.h"

namespace hmc {

// Places the markers on `face` with a seeded jitter of `jitter_mm` (std,
// clamped to 2 std) in the face plane. A marker never sits in the mouth
// slit: it is moved off it, away from the mouth.
std::vector<Marker> LayoutMarkers(const FaceMesh& face, uint64_t seed,
                                  double jitter_mm);

}  // namespace hmc
