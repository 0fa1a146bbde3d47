// The day's paint (docs/registration.md, "The truth of painted dots"): every
// dot of a synthetic shot painted off its marker point by a seeded
// tangential offset, some left unpainted, some rubbed off mid-take; what
// `hmc synth shot --paint_*` renders and records as painted_markers.csv.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/actor.h"
#include "core/options.h"

namespace hmc {

struct PaintOptions {
  double jitter_mm = 0;   // std of each dot's tangential offset per axis (mm; 0 = on the marker points)
  int missing = 0;        // dots left unpainted
  std::string lost_at;    // "F:N": N dots rubbed off from frame F on ("" = none)
  int seed = -1;          // seed of the painting (-1 = the shot's seed: the takes of a day share it)

  void Register(OptionFields* fields);  // paint_* at the top level
  bool Check() const;
  bool Any() const { return jitter_mm > 0 || missing > 0 || !lost_at.empty(); }
  // lost_at parsed: {frame, count}; {0, 0} when empty.
  std::pair<int, int> Lost() const;
};

struct PaintedDots {
  std::vector<Marker> markers;       // the painted dots (unpainted ones left out), in package order
  std::vector<std::string> missing;  // markers left unpainted
  int lost_frame = 0;                // from this frame on (0 = none) ...
  std::vector<std::string> lost;     // ... these dots are gone
  // The markers painted at `frame`.
  std::vector<Marker> At(int frame) const;
};

// Paints `markers` on `neutral`: each moved by a Gaussian offset in its
// triangle's tangent plane (jitter_mm per axis) and put back on the surface
// at the closest point; `seed`: the painting's (PaintOptions::seed resolved).
PaintedDots PaintDots(const TriMesh& neutral, const std::vector<Marker>& markers,
                      const PaintOptions& options, uint64_t seed);

}  // namespace hmc
