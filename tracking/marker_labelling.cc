// Labelling at the reference frame (docs/tracking.md, "Labelling"): the
// actor's marker layout, and the registration of it to the stereo candidate
// points of the reference frame (tracking/marker_tracker.h, steps 1-2).
#include "tracking/marker_tracker.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <unordered_map>

#include <Eigen/Geometry>
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "tracking/marker_geometry.h"

namespace hmc {

MarkerLayout MakeMarkerLayout(const Actor& actor, int neighbours) {
  MarkerLayout layout;
  const MatX3d normals = VertexNormals(actor.neutral.V, actor.neutral.F);
  for (const Marker& marker : actor.markers) {
    layout.names.push_back(marker.name);
    layout.positions.push_back(EvaluateSurfacePoint(marker.point, actor.neutral.F, actor.neutral.V));
    const Vec3 n = EvaluateSurfacePoint(marker.point, actor.neutral.F, normals);
    layout.normals.push_back(n.norm() > 0 ? Vec3(n.normalized()) : Vec3(0, 0, 1));
  }
  if (actor.jaw_rig) {
    layout.jaw_rig = *actor.jaw_rig;
    layout.jaw_rig.weights.resize(0);
    for (const Marker& marker : actor.markers) {
      double w = 0;
      for (int i = 0; i < 3; ++i) {
        w += marker.point.bary[i] * actor.jaw_rig->weights(actor.neutral.F(marker.point.face, i));
      }
      layout.jaw_weights.push_back(w);
    }
    for (const Shape& shape : actor.shapes) {
      const std::array<double, 3> p = shape.jaw.ToArray();
      for (int i = 0; i < 3; ++i) {
        layout.jaw_lower[i] = std::min(layout.jaw_lower[i], p[i]);
        layout.jaw_upper[i] = std::max(layout.jaw_upper[i], p[i]);
      }
    }
    for (int i = 0; i < 3; ++i) {
      const double margin = std::max(0.25 * (layout.jaw_upper[i] - layout.jaw_lower[i]), 1.0);
      layout.jaw_lower[i] -= margin;
      layout.jaw_upper[i] += margin;
    }
  }
  const int n = static_cast<int>(layout.positions.size());
  layout.neighbours.resize(n);
  for (int i = 0; i < n; ++i) {
    std::vector<std::pair<double, int>> by_distance;
    for (int j = 0; j < n; ++j) {
      if (j != i) by_distance.push_back({(layout.positions[i] - layout.positions[j]).norm(), j});
    }
    std::sort(by_distance.begin(), by_distance.end());
    for (int k = 0; k < std::min<int>(neighbours, by_distance.size()); ++k) {
      layout.neighbours[i].push_back(by_distance[k].second);
    }
  }
  return layout;
}

std::vector<Vec3> MarkerLayout::PosedPositions(const JawPose& pose) const {
  if (jaw_weights.empty() || pose.IsZero()) return positions;
  const Rigid3 t = jaw_rig.Transform(pose);
  std::vector<Vec3> posed(positions.size());
  for (size_t k = 0; k < positions.size(); ++k) posed[k] = SkinPoint(t, positions[k], jaw_weights[k]);
  return posed;
}

namespace {

double AngleDeg(const Rigid3& t) {
  return Eigen::AngleAxisd(t.linear()).angle() * 180 / M_PI;
}

}  // namespace

void MarkerTracker::Register(const std::vector<std::vector<DotDetection>>& detections) {
  labelling_ = ReferenceLabelling();
  if (rig_.cameras.size() < 2 || detections.size() < 2) {
    labelling_.reason = "two cameras are needed";
    return;
  }
  const StereoPairs pairs = PairDetections(rig_, detections, options_.pair_gap_mm);
  const std::vector<Vec3>& points = pairs.points;
  const std::vector<std::pair<int, int>>& pair_of = pairs.pair_of;
  std::vector<int> partners0(detections[0].size(), 0), partners1(detections[1].size(), 0);
  for (const auto& [i, j] : pair_of) {
    ++partners0[i];
    ++partners1[j];
  }
  labelling_.candidate_points = static_cast<int>(points.size());
  if (points.size() < 3) {
    labelling_.reason = fmt::format("only {} stereo pairs", points.size());
    return;
  }
  std::vector<int> unique;
  for (size_t p = 0; p < points.size(); ++p) {
    if (partners0[pair_of[p].first] == 1 && partners1[pair_of[p].second] == 1) {
      unique.push_back(static_cast<int>(p));
    }
  }
  if (unique.size() < 3) {
    unique.resize(points.size());
    for (size_t p = 0; p < points.size(); ++p) unique[p] = static_cast<int>(p);
  }
  const std::vector<Vec3>& M = layout_.positions;
  const int num_markers = static_cast<int>(M.size());
  Vec3 centre = Vec3::Zero();
  for (const Vec3& m : M) centre += m / num_markers;
  const double search_mm = 1.5 * options_.max_offset_mm + 2;
  const double search_deg = 1.5 * options_.max_offset_deg + 2;
  const double search_sin = std::sin(std::min(90.0, search_deg) * M_PI / 180);
  const PointGrid grid(points, options_.inlier_mm);

  // Markers matched by a pose, and their squared residuals.
  auto score = [&](const Rigid3& helmet_from_head, double* sum_sq) {
    int count = 0;
    *sum_sq = 0;
    for (const Vec3& m : M) {
      double d = 0;
      if (grid.Nearest(helmet_from_head * m, options_.inlier_mm, &d) >= 0) {
        ++count;
        *sum_sq += d * d;
      }
    }
    return count;
  };
  auto plausible = [&](const Rigid3& t) {
    return AngleDeg(t) <= search_deg && (t * centre - centre).norm() <= search_mm + 1e-9;
  };
  Rigid3 best = Rigid3::Identity();
  double best_sq = 0;
  int best_count = score(best, &best_sq);
  std::mt19937 rng(12345);
  std::uniform_int_distribution<int> pick(0, static_cast<int>(unique.size()) - 1);
  // Candidate markers of a point: where it may be under the prior.
  auto candidates = [&](const Vec3& p) {
    std::vector<int> out;
    for (int k = 0; k < num_markers; ++k) {
      const double reach = search_mm + search_sin * (M[k] - centre).norm() + options_.inlier_mm;
      if ((M[k] - p).norm() <= reach) out.push_back(k);
    }
    return out;
  };
  const double tol = options_.triple_tolerance_mm;
  for (int s = 0; s < options_.ransac_samples; ++s) {
    const int a = unique[pick(rng)], b = unique[pick(rng)], c = unique[pick(rng)];
    const Vec3 &pa = points[a], &pb = points[b], &pc = points[c];
    const double dab = (pa - pb).norm(), dac = (pa - pc).norm(), dbc = (pb - pc).norm();
    if (dab < 15 || dac < 15 || dbc < 15) continue;
    if ((pb - pa).cross(pc - pa).norm() < 0.2 * dab * dac) continue;  // nearly collinear
    const std::vector<int> ca = candidates(pa), cb = candidates(pb), cc = candidates(pc);
    for (int ka : ca) {
      for (int kb : cb) {
        if (kb == ka || std::abs((M[ka] - M[kb]).norm() - dab) > tol) continue;
        for (int kc : cc) {
          if (kc == ka || kc == kb) continue;
          if (std::abs((M[ka] - M[kc]).norm() - dac) > tol ||
              std::abs((M[kb] - M[kc]).norm() - dbc) > tol) {
            continue;
          }
          const Rigid3 t = FitRigid({M[ka], M[kb], M[kc]}, {pa, pb, pc});
          if (!plausible(t)) continue;
          double sq = 0;
          const int count = score(t, &sq);
          if (count > best_count || (count == best_count && sq < best_sq)) {
            best = t;
            best_count = count;
            best_sq = sq;
          }
        }
      }
    }
  }
  spdlog::debug("labelling: {} candidate points, {} unique, RANSAC best {} markers", points.size(),
                unique.size(), best_count);
  jaw_ = JawPose();
  // ICP with mutual nearest neighbours, gate shrinking to inlier_mm / 2.
  int inliers = 0;
  double rms = 0;
  auto icp = [&](const std::vector<Vec3>& positions) {
    double gate = options_.inlier_mm;
    for (int iteration = 0; iteration < 20; ++iteration) {
      std::vector<int> nearest_point(num_markers, -1);
      std::vector<double> nearest_d(num_markers, 0);
      for (int k = 0; k < num_markers; ++k) {
        nearest_point[k] = grid.Nearest(best * positions[k], gate, &nearest_d[k]);
      }
      // Mutual: the point's nearest marker is k.
      std::unordered_map<int, std::pair<double, int>> point_best;
      for (int k = 0; k < num_markers; ++k) {
        if (nearest_point[k] < 0) continue;
        auto it = point_best.find(nearest_point[k]);
        if (it == point_best.end() || nearest_d[k] < it->second.first) {
          point_best[nearest_point[k]] = {nearest_d[k], k};
        }
      }
      std::vector<Vec3> from, to;
      double sum_sq = 0;
      for (const auto& [p, dk] : point_best) {
        from.push_back(positions[dk.second]);
        to.push_back(points[p]);
        sum_sq += dk.first * dk.first;
      }
      if (from.size() < 3) break;
      inliers = static_cast<int>(from.size());
      rms = std::sqrt(sum_sq / inliers);
      best = FitRigid(from, to);
      gate = std::max(0.5 * options_.inlier_mm, 0.85 * gate);
    }
  };
  icp(M);
  // The jaw (file comment, step 2): the pose whose skinned layout puts the
  // most jaw-weighted markers on candidate points under the head pose, on a
  // 1-unit grid over the dataset's range, then a 0.25-unit grid around it.
  positions_ = M;
  if (!layout_.jaw_weights.empty()) {
    std::vector<int> moving;
    for (int k = 0; k < num_markers; ++k) {
      if (layout_.jaw_weights[k] > 1e-6) moving.push_back(k);
    }
    const Rigid3 head = best;
    auto jaw_score = [&](const JawPose& pose, double* sum_sq) {
      const Rigid3 t = layout_.jaw_rig.Transform(pose);
      int count = 0;
      *sum_sq = 0;
      for (int k : moving) {
        double d = 0;
        if (grid.Nearest(head * SkinPoint(t, M[k], layout_.jaw_weights[k]), options_.inlier_mm, &d) >= 0) {
          ++count;
          *sum_sq += d * d;
        }
      }
      return count;
    };
    JawPose jaw;
    double jaw_sq = 0;
    int jaw_count = jaw_score(jaw, &jaw_sq);
    auto search = [&](const std::array<double, 3>& lo, const std::array<double, 3>& hi, double step) {
      ForEachJawPose(lo, hi, step, [&](const JawPose& pose) {
        double sq = 0;
        const int count = jaw_score(pose, &sq);
        if (count > jaw_count || (count == jaw_count && sq < jaw_sq)) {
          jaw = pose;
          jaw_count = count;
          jaw_sq = sq;
        }
      });
    };
    search(layout_.jaw_lower, layout_.jaw_upper, 1.0);
    const std::array<double, 3> coarse = jaw.ToArray();
    search({coarse[0] - 1, coarse[1] - 1, coarse[2] - 1},
           {coarse[0] + 1, coarse[1] + 1, coarse[2] + 1}, 0.25);
    if (!jaw.IsZero()) {
      positions_ = layout_.PosedPositions(jaw);
      icp(positions_);
    }
    labelling_.jaw = jaw;
    jaw_ = jaw;
    spdlog::debug("labelling: jaw open {:.2f} deg, lateral {:.2f} deg, protrude {:.2f} mm: {} of {} "
                  "jaw-weighted markers on a point",
                  jaw.open_deg, jaw.lateral_deg, jaw.protrude_mm, jaw_count, moving.size());
  }
  labelling_.helmet_from_head = best;
  labelling_.inliers = inliers;
  labelling_.rms_mm = rms;
  if (inliers < std::max(3, num_markers / 5)) {
    labelling_.reason =
        fmt::format("registration matched only {} of {} markers", inliers, num_markers);
    return;
  }
  labelling_.ok = true;
}

}  // namespace hmc
