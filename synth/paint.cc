#include "synth/paint.h"

#include <algorithm>
#include <numeric>
#include <set>

#include "core/day_markers.h"
#include "core/error.h"
#include "core/text.h"
#include "synth/synth_random.h"

namespace hmc {

void PaintOptions::Register(OptionFields* fields) {
  fields->Add("paint_jitter_mm", &jitter_mm,
              "each painted dot off its marker point by a tangential Gaussian offset of this std "
              "per axis (mm; 0 = on the marker points)")
      .AtLeast(0)
      .AtMost(10);
  fields->Add("paint_missing", &missing, "dots left unpainted").AtLeast(0).AtMost(1000);
  fields->Add("paint_lost_at", &lost_at, "F:N: N dots rubbed off from frame F on (\"\" = none)");
  fields->Add("paint_seed", &seed,
              "seed of the painting (-1 = the shot's seed, so the takes of a day share it)")
      .AtLeast(-1);
}

std::pair<int, int> PaintOptions::Lost() const {
  if (lost_at.empty()) return {0, 0};
  const size_t colon = lost_at.find(':');
  long long frame = 0, count = 0;
  if (colon == std::string::npos || !ParseInteger(lost_at.substr(0, colon), &frame) ||
      !ParseInteger(lost_at.substr(colon + 1), &count) || frame < 1 || count < 0) {
    return {-1, -1};
  }
  return {static_cast<int>(frame), static_cast<int>(count)};
}

bool PaintOptions::Check() const {
  CHECK_OPTION_LIMITS();
  CHECK_OPTION(Lost().first >= 0);  // paint_lost_at: F:N, frame >= 1, count >= 0
  return true;
}

std::vector<Marker> PaintedDots::At(int frame) const {
  if (lost_frame <= 0 || frame < lost_frame) return markers;
  std::vector<Marker> out;
  for (const Marker& m : markers) {
    if (std::find(lost.begin(), lost.end(), m.name) == lost.end()) out.push_back(m);
  }
  return out;
}

PaintedDots PaintDots(const TriMesh& neutral, const std::vector<Marker>& markers,
                      const PaintOptions& options, uint64_t seed) {
  PaintedDots out;
  const int n = static_cast<int>(markers.size());
  SynthRandom pick = SynthRandom::Stream(seed, 0x9A1A7);
  std::vector<int> order(n);
  std::iota(order.begin(), order.end(), 0);
  for (int i = n - 1; i > 0; --i) std::swap(order[i], order[pick.Index(i + 1)]);
  const auto [lost_frame, lost_count] = options.Lost();
  const int missing = std::min(options.missing, n);
  const int lost = std::min(lost_count, n - missing);
  std::set<int> unpainted(order.begin(), order.begin() + missing);
  std::set<int> rubbed(order.begin() + missing, order.begin() + missing + lost);
  out.lost_frame = lost > 0 ? lost_frame : 0;
  SynthRandom jitter = SynthRandom::Stream(seed, 0x9A1A8);
  for (int m = 0; m < n; ++m) {
    // Drawn for every marker, so a dot's offset does not depend on which are missing.
    const double u = jitter.Normal(), v = jitter.Normal();
    if (unpainted.count(m)) {
      out.missing.push_back(markers[m].name);
      continue;
    }
    if (rubbed.count(m)) out.lost.push_back(markers[m].name);
    Marker painted = markers[m];
    if (options.jitter_mm > 0) {
      const int f = painted.point.face;
      const Vec3 a = neutral.V.row(neutral.F(f, 0)), b = neutral.V.row(neutral.F(f, 1)),
                 c = neutral.V.row(neutral.F(f, 2));
      const Vec3 normal = (b - a).cross(c - a).normalized();
      const Vec3 t1 = (b - a - (b - a).dot(normal) * normal).normalized();
      const Vec3 t2 = normal.cross(t1);
      const Vec3 p = EvaluateSurfacePoint(painted.point, neutral.F, neutral.V);
      painted.point = ClosestSurfacePoint(neutral, p + options.jitter_mm * (u * t1 + v * t2));
      painted.vertex = -1;
    }
    out.markers.push_back(painted);
  }
  return out;
}

}  // namespace hmc
