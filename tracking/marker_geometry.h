// Geometry shared by the labelling (tracking/marker_labelling.cc) and the
// tracking (tracking/marker_tracker.cc) of the painted dots
// (docs/tracking.md): a hash grid of 3D points, the closed-form rigid fit
// (Umeyama 1991), the stereo candidate points of two cameras' detections
// and the walk over a grid of jaw poses.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <unordered_map>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "core/calibration.h"
#include "core/jaw.h"
#include "core/types.h"
#include "tracking/dot_detector.h"

namespace hmc {

// Points hashed in cubes of `cell` mm for radius queries up to one cell.
class PointGrid {
 public:
  PointGrid(const std::vector<Vec3>& points, double cell) : points_(points), cell_(cell) {
    for (int i = 0; i < static_cast<int>(points.size()); ++i) cells_[Key(points[i])].push_back(i);
  }
  // Nearest point within `radius` (<= cell) of q, or -1.
  int Nearest(const Vec3& q, double radius, double* distance) const {
    int best = -1;
    double best_d = radius;
    const Eigen::Vector3i c = Cell(q);
    for (int dx = -1; dx <= 1; ++dx) {
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dz = -1; dz <= 1; ++dz) {
          auto it = cells_.find(Pack(c + Eigen::Vector3i(dx, dy, dz)));
          if (it == cells_.end()) continue;
          for (int i : it->second) {
            const double d = (points_[i] - q).norm();
            if (d < best_d) {
              best_d = d;
              best = i;
            }
          }
        }
      }
    }
    if (distance) *distance = best_d;
    return best;
  }

 private:
  Eigen::Vector3i Cell(const Vec3& p) const {
    return Eigen::Vector3i(static_cast<int>(std::floor(p.x() / cell_)),
                           static_cast<int>(std::floor(p.y() / cell_)),
                           static_cast<int>(std::floor(p.z() / cell_)));
  }
  static int64_t Pack(const Eigen::Vector3i& c) {
    return (static_cast<int64_t>(c.x() + (1 << 20)) << 42) ^
           (static_cast<int64_t>(c.y() + (1 << 20)) << 21) ^ static_cast<int64_t>(c.z() + (1 << 20));
  }
  int64_t Key(const Vec3& p) const { return Pack(Cell(p)); }
  const std::vector<Vec3>& points_;
  double cell_;
  std::unordered_map<int64_t, std::vector<int>> cells_;
};

// The rigid transform that best maps `from` onto `to` (least squares, no
// scale).
Rigid3 FitRigid(const std::vector<Vec3>& from, const std::vector<Vec3>& to);

// Calls visit(pose) for every jaw pose lo + (i, j, k) x step within [lo, hi]
// (open_deg, lateral_deg, protrude_mm).
template <typename Visit>
void ForEachJawPose(const std::array<double, 3>& lo, const std::array<double, 3>& hi, double step,
                    Visit&& visit) {
  std::array<int, 3> n{};
  for (int i = 0; i < 3; ++i) n[i] = static_cast<int>(std::floor((hi[i] - lo[i]) / step + 1e-9));
  for (int a = 0; a <= n[0]; ++a) {
    for (int b = 0; b <= n[1]; ++b) {
      for (int c = 0; c <= n[2]; ++c) {
        visit(JawPose::FromArray({lo[0] + a * step, lo[1] + b * step, lo[2] + c * step}));
      }
    }
  }
}

// Every cam0 x cam1 pair of detections whose rays pass within gap_mm: its
// midpoint (helmet space) and the two detections; and per cam0 detection
// the smallest gap to any cam1 ray (infinite if none meets it).
struct StereoPairs {
  std::vector<Vec3> points;
  std::vector<std::pair<int, int>> pair_of;
  std::vector<double> smallest_gap0;
};
StereoPairs PairDetections(const HelmetRig& rig,
                           const std::vector<std::vector<DotDetection>>& detections, double gap_mm);

}  // namespace hmc
