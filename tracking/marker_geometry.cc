#include "tracking/marker_geometry.h"

#include <algorithm>
#include <limits>

#include <Eigen/Geometry>

#include "tracking/stereo_rays.h"

namespace hmc {

Rigid3 FitRigid(const std::vector<Vec3>& from, const std::vector<Vec3>& to) {
  Eigen::Matrix3Xd a(3, from.size()), b(3, to.size());
  for (size_t i = 0; i < from.size(); ++i) {
    a.col(i) = from[i];
    b.col(i) = to[i];
  }
  Rigid3 out = Rigid3::Identity();
  out.matrix() = Eigen::umeyama(a, b, false);
  return out;
}

StereoPairs PairDetections(const HelmetRig& rig,
                           const std::vector<std::vector<DotDetection>>& detections, double gap_mm) {
  StereoPairs out;
  std::vector<Ray3> rays0, rays1;
  for (const DotDetection& d : detections[0]) rays0.push_back(PixelRay(rig.cameras[0], d.pixel));
  for (const DotDetection& d : detections[1]) rays1.push_back(PixelRay(rig.cameras[1], d.pixel));
  out.smallest_gap0.assign(rays0.size(), std::numeric_limits<double>::infinity());
  for (size_t i = 0; i < rays0.size(); ++i) {
    for (size_t j = 0; j < rays1.size(); ++j) {
      const RayApproach a = ClosestApproach(rays0[i], rays1[j]);
      if (a.ok) out.smallest_gap0[i] = std::min(out.smallest_gap0[i], a.gap);
      if (!a.ok || a.gap > gap_mm) continue;
      out.points.push_back(a.midpoint);
      out.pair_of.push_back({static_cast<int>(i), static_cast<int>(j)});
    }
  }
  return out;
}

}  // namespace hmc
