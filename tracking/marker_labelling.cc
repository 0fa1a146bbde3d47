// Labelling at the reference frame (docs/tracking.md, "Labelling"): the
// actor's marker layout, and the registration of it to the stereo candidate
// points of the reference frame (tracking/marker_tracker.h, steps 1-2).
#include "tracking/marker_tracker.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <random>
#include <unordered_map>

#include <Eigen/Geometry>
#include <Eigen/Eigenvalues>
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "stabilization/head_fit.h"
#include "stabilization/marker_model.h"
#include "tracking/marker_geometry.h"

namespace hmc {

namespace {

// The expression model of the labelling (docs/tracking.md, "Labelling",
// step 2): the principal components of the dataset's marker displacements
// (stabilization/marker_model.h; unskinned by each shape's jaw pose, since
// the jaw search poses the layout first), uncentred so that zero weights
// are the neutral, each scaled to the RMS of its coefficient over the
// shapes. Kept: the components that explain 99.9 % of the displacements'
// energy, at most kMaxExpressionComponents.
constexpr int kMaxExpressionComponents = 40;

void SetExpressionBasis(const Actor& actor, MarkerLayout* layout) {
  if (actor.shapes.empty() || actor.markers.empty()) return;
  const MarkerModel model = ComputeMarkerModel(actor);
  const Eigen::MatrixXd& d = model.unskinned_displacement;
  // d = U S V^T from the eigen-decomposition of the smaller Gram matrix
  // (not Eigen's BDCSVD: under AddressSanitizer our build and Ceres'
  // library allocate its shared internals differently).
  const bool by_shapes = d.cols() <= d.rows();
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(
      by_shapes ? Eigen::MatrixXd(d.transpose() * d) : Eigen::MatrixXd(d * d.transpose()));
  const Eigen::VectorXd energy = eig.eigenvalues().reverse().cwiseMax(0.0);  // S^2, descending
  const Eigen::MatrixXd vectors = eig.eigenvectors().rowwise().reverse();     // V or U
  const double total = energy.sum();
  if (!(total > 0)) return;
  int used = 0;
  double explained = 0;
  while (used < std::min<int>(kMaxExpressionComponents, energy.size()) &&
         explained < 0.999 * total && energy[used] > 0) {
    explained += energy[used++];
  }
  if (used == 0) return;
  // Shape n's coefficient on the scaled column i is sqrt(N) V(n, i);
  // the column is U_i S_i / sqrt(N).
  const double root_n = std::sqrt(static_cast<double>(d.cols()));
  const Eigen::VectorXd s = energy.head(used).cwiseSqrt();
  if (by_shapes) {
    const Eigen::MatrixXd v = vectors.leftCols(used);
    layout->expression_basis = d * v / root_n;
    layout->expression_shapes = root_n * v.transpose();
  } else {
    const Eigen::MatrixXd u = vectors.leftCols(used);
    layout->expression_basis = u * (s / root_n).asDiagonal();
    layout->expression_shapes = root_n * s.cwiseInverse().asDiagonal() * u.transpose() * d;
  }
}

}  // namespace

MarkerLayout MakeMarkerLayout(const Actor& actor, int neighbours) {
  MarkerLayout layout;
  const MatX3d normals = VertexNormals(actor.neutral.V, actor.neutral.F);
  for (const Marker& marker : actor.markers) {
    layout.names.push_back(marker.name);
    layout.positions.push_back(EvaluateSurfacePoint(marker.point, actor.neutral.F, actor.neutral.V));
    const Vec3 n = EvaluateSurfacePoint(marker.point, actor.neutral.F, normals);
    layout.normals.push_back(n.norm() > 0 ? Vec3(n.normalized()) : Vec3(0, 0, 1));
  }
  // The border of the neutral mesh: edges of one triangle (the lips'
  // opening, the mask's rim).
  std::map<std::pair<int, int>, int> edge_faces;
  const MatX3i& F = actor.neutral.F;
  for (int f = 0; f < F.rows(); ++f) {
    for (int i = 0; i < 3; ++i) {
      const int a = F(f, i), b = F(f, (i + 1) % 3);
      ++edge_faces[{std::min(a, b), std::max(a, b)}];
    }
  }
  std::vector<Vec3> border;
  for (const auto& [edge, faces] : edge_faces) {
    if (faces != 1) continue;
    border.push_back(actor.neutral.V.row(edge.first).transpose());
    border.push_back(actor.neutral.V.row(edge.second).transpose());
  }
  for (const Vec3& p : layout.positions) {
    double d = std::numeric_limits<double>::infinity();
    for (const Vec3& b : border) d = std::min(d, (b - p).norm());
    layout.border_mm.push_back(d);
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
  SetExpressionBasis(actor, &layout);
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

// A marker of the layout and its mutual nearest candidate point.
struct PointMatch {
  int marker = -1;
  int point = -1;
  double distance = 0;
};

// The markers at `positions` (head space) under helmet_from_head whose
// nearest candidate point within `gate` has no nearer marker.
std::vector<PointMatch> MutualMatches(const PointGrid& grid, const Rigid3& helmet_from_head,
                                      const std::vector<Vec3>& positions, double gate) {
  const int num_markers = static_cast<int>(positions.size());
  std::vector<int> nearest_point(num_markers, -1);
  std::vector<double> nearest_d(num_markers, 0);
  for (int k = 0; k < num_markers; ++k) {
    nearest_point[k] = grid.Nearest(helmet_from_head * positions[k], gate, &nearest_d[k]);
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
  std::vector<PointMatch> out;
  out.reserve(point_best.size());
  for (const auto& [p, dk] : point_best) out.push_back({dk.second, p, dk.first});
  return out;
}

// The robust loss and the ridge of the expression fit, and how its
// components are let in: a few first, all at the end (coarse to fine, so
// that the first matches, made against a layout still far from the face,
// cannot bend the many fine components onto wrong points).
constexpr double kExpressionLossMm = 1.0;
constexpr double kExpressionRidge = 0.1;  // mm^2 per (unit RMS coefficient)^2
constexpr int kExpressionStages[] = {6, 12, 20, kMaxExpressionComponents};
// The search for its start: shapes added at most, and their scales.
constexpr int kSearchedShapes = 6;
constexpr double kShapeScales[] = {0.25, 0.5, 0.75, 1.0, 1.25, -0.5};
// The expressed layout bends: it is taken only when it explains at least
// this share of the detections of the camera with fewer (measured: 0.75-
// 0.93 on broad-rig shots, 0.34 on a rig 2 mm / 1 degree off, where it
// had bent onto wrong points).
constexpr double kExpressedShareOfDetections = 0.5;
// Fewer unique stereo pairs than this: RANSAC draws from all of them.
constexpr size_t kMinUniquePairs = 12;
// The stereo pose is suspected when the median over cam0's dots of the
// smallest gap to a cam1 ray exceeds kCalibratedGapMm (measured: 0.007-
// 0.009 mm with the true calibration of synthetic shots, 0.16-0.38 mm with
// a rig 2 mm / 1 degree off), or fewer than this share of a camera's dots
// pair (on a calibrated rig most painted dots are seen by both cameras).
constexpr double kCalibratedGapMm = 0.1;
constexpr double kPairedShareOfAGoodCalibration = 0.5;

struct ExpressedLayout {
  Rigid3 helmet_from_head = Rigid3::Identity();
  std::vector<Vec3> positions;  // head space
  int inliers = 0;              // mutual matches within inlier_mm / 2
  double rms_mm = 0;
};

// A start for the expression by a search over the dataset's shapes, the
// pose fixed (docs/tracking.md, "Labelling", step 2): a mouth opened wide
// moves the chin dots 30-40 mm, farther than any matching gate reaches.
// Greedily, up to kSearchedShapes times, the dataset shape and scale
// (kShapeScales) whose addition puts the most markers within inlier_mm of
// a candidate point (then the smallest sum of squares) are added, as the
// jaw search does over jaw poses; it stops when no addition gains a marker.
Eigen::VectorXd SearchExpressionShapes(const std::vector<Vec3>& base, const MarkerLayout& layout,
                                       const PointGrid& grid, const Rigid3& helmet_from_head,
                                       double inlier_mm) {
  const Eigen::MatrixXd& basis = layout.expression_basis;
  const int num_markers = static_cast<int>(base.size());
  const int num_shapes = static_cast<int>(layout.expression_shapes.cols());
  const Eigen::MatrixXd shapes = basis * layout.expression_shapes;  // 3K x N (mm)
  Eigen::VectorXd weights = Eigen::VectorXd::Zero(basis.cols());
  std::vector<Vec3> current = base;  // head space, at `weights`
  auto score = [&](int shape, double scale, double* sum_sq) {
    int count = 0;
    *sum_sq = 0;
    for (int k = 0; k < num_markers; ++k) {
      Vec3 p = current[k];
      if (shape >= 0) p += scale * shapes.block<3, 1>(3 * k, shape);
      double d = 0;
      if (grid.Nearest(helmet_from_head * p, inlier_mm, &d) >= 0) {
        ++count;
        *sum_sq += d * d;
      }
    }
    return count;
  };
  double best_sq = 0;
  int best_count = score(-1, 0, &best_sq);
  for (int round = 0; round < kSearchedShapes; ++round) {
    int best_shape = -1;
    double best_scale = 0;
    for (int n = 0; n < num_shapes; ++n) {
      for (const double scale : kShapeScales) {
        double sq = 0;
        const int count = score(n, scale, &sq);
        if (count > best_count || (count == best_count && best_shape >= 0 && sq < best_sq)) {
          best_shape = n;
          best_scale = scale;
          best_count = count;
          best_sq = sq;
        }
      }
    }
    if (best_shape < 0) break;
    weights += best_scale * layout.expression_shapes.col(best_shape);
    for (int k = 0; k < num_markers; ++k) {
      current[k] += best_scale * shapes.block<3, 1>(3 * k, best_shape);
    }
    spdlog::debug("labelling: expression start + {:.2f} x dataset shape {}: {} markers on a point",
                  best_scale, best_shape, best_count);
  }
  return weights;
}

// The registration with the dataset's expression (docs/tracking.md,
// "Labelling", step 2): from the shape search's weights, ICP whose model is
// the layout `base` plus the expression basis, the pose and the weights of
// each round fitted jointly and robustly to the matched points by the head
// fit (stabilization/head_fit.h), from `start`; the gate shrinks from
// 2 x inlier_mm to inlier_mm / 2, and the components are let in a few at
// a time.
ExpressedLayout FitExpressedLayout(const std::vector<Vec3>& base, const MarkerLayout& layout,
                                   const std::vector<Vec3>& points, const PointGrid& grid,
                                   const Rigid3& start, double inlier_mm) {
  const Eigen::MatrixXd& basis = layout.expression_basis;
  const int num_markers = static_cast<int>(base.size());
  const int num_components = static_cast<int>(basis.cols());
  Eigen::VectorXd weights = SearchExpressionShapes(base, layout, grid, start, inlier_mm);
  auto expressed = [&] {
    std::vector<Vec3> out = base;
    for (int k = 0; k < num_markers; ++k) out[k] += basis.middleRows<3>(3 * k) * weights;
    return out;
  };
  HeadFitOptions fit_options;
  fit_options.loss = RobustLoss::kCauchy;
  fit_options.loss_scale_mm = kExpressionLossMm;
  fit_options.ridge = kExpressionRidge;
  fit_options.tolerance_mm = 1e-3;
  ExpressedLayout out;
  out.helmet_from_head = start;
  double gate = 2 * inlier_mm;
  for (const int stage : kExpressionStages) {
    const int used = std::min(stage, num_components);
    std::vector<int> previous;
    for (int iteration = 0; iteration < 12; ++iteration) {
      std::vector<PointMatch> matches = MutualMatches(grid, out.helmet_from_head, expressed(), gate);
      if (static_cast<int>(matches.size()) < std::max(6, used)) break;
      std::sort(matches.begin(), matches.end(),
                [](const PointMatch& a, const PointMatch& b) { return a.marker < b.marker; });
      std::vector<int> matched;
      for (const PointMatch& m : matches) matched.push_back(m.marker);
      if (matched == previous && gate <= 0.5 * inlier_mm) break;
      previous = matched;
      const int n = static_cast<int>(matches.size());
      Eigen::Matrix3Xd a(3, n), q(3, n);
      Eigen::MatrixXd b(3 * n, used);
      // The components not yet let in stay where the search put them.
      const int rest = num_components - used;
      for (int i = 0; i < n; ++i) {
        const int k = matches[i].marker;
        a.col(i) = points[matches[i].point];
        q.col(i) = base[k] + basis.block(3 * k, used, 3, rest) * weights.tail(rest);
        b.middleRows<3>(3 * i) = basis.block(3 * k, 0, 3, used);
      }
      const HeadFitResult fit = FitHeadAndExpression(a, q, b, Eigen::VectorXd::Ones(n),
                                                     out.helmet_from_head.inverse(), fit_options);
      if (!fit.ok) break;
      out.helmet_from_head = fit.head_from_helmet.inverse();
      weights.head(used) = fit.shape_weights;
      gate = std::max(0.5 * inlier_mm, 0.85 * gate);
    }
    if (used == num_components) break;
  }
  out.positions = expressed();
  const std::vector<PointMatch> matches =
      MutualMatches(grid, out.helmet_from_head, out.positions, 0.5 * inlier_mm);
  double sum_sq = 0;
  for (const PointMatch& m : matches) sum_sq += m.distance * m.distance;
  out.inliers = static_cast<int>(matches.size());
  out.rms_mm = out.inliers > 0 ? std::sqrt(sum_sq / out.inliers) : 0.0;
  return out;
}

// The likely cause of a failed registration (issue 44, item 6), from the
// stereo rays: rays that miss each other (the median smallest gap, the
// share of dots paired) mean a calibration whose stereo pose is off; dots that pair
// but do not fit the layout mean another actor or markers.csv, or a
// reference frame far from the layout (an extreme expression, occlusion).
std::string LikelyCause(const ReferenceLabelling& labelling, double pair_gap_mm) {
  if (labelling.median_gap_mm > kCalibratedGapMm ||
      labelling.paired_share < kPairedShareOfAGoodCalibration) {
    return fmt::format(
        ": the two cameras' rays through the dots miss each other by {:.2f} mm (median of the "
        "nearest; well under {} mm on a calibrated rig) and {:.0f} % of a camera's dots have a "
        "partner within pair_gap_mm ({} mm), so the calibration's stereo pose is likely off (a "
        "nominal calibration.yaml: refine it from the helmet tags with `hmc calibrate`, or run "
        "`hmc run` without --calibrate false)",
        labelling.median_gap_mm, kCalibratedGapMm, 100 * labelling.paired_share, pair_gap_mm);
  }
  return fmt::format(
      ": the dots pair up in stereo (rays {:.3f} mm apart, median) but do not fit the actor's "
      "marker layout: likely the actor or its markers.csv is not the one painted on this face "
      "(`hmc actor check`), or the reference frame holds an extreme expression or hidden dots: "
      "choose another frame with --reference_frame N (`hmc track` and `hmc run`)",
      labelling.median_gap_mm);
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
  auto paired_share = [](const std::vector<int>& partners) {
    const auto paired = std::count_if(partners.begin(), partners.end(), [](int n) { return n > 0; });
    return partners.empty() ? 0.0 : static_cast<double>(paired) / partners.size();
  };
  labelling_.paired_share = std::min(paired_share(partners0), paired_share(partners1));
  if (!pairs.smallest_gap0.empty()) {
    std::vector<double> gaps = pairs.smallest_gap0;
    std::nth_element(gaps.begin(), gaps.begin() + gaps.size() / 2, gaps.end());
    labelling_.median_gap_mm = gaps[gaps.size() / 2];
  }
  spdlog::debug("labelling: median smallest ray gap {:.3f} mm, paired share {:.2f}",
                labelling_.median_gap_mm, labelling_.paired_share);
  if (points.size() < 3) {
    labelling_.reason = fmt::format("only {} stereo pairs{}", points.size(),
                                    LikelyCause(labelling_, options_.pair_gap_mm));
    return;
  }
  std::vector<int> unique;
  for (size_t p = 0; p < points.size(); ++p) {
    if (partners0[pair_of[p].first] == 1 && partners1[pair_of[p].second] == 1) {
      unique.push_back(static_cast<int>(p));
    }
  }
  // A few unique pairs are no sample: the triples drawn from three or four
  // points are the same few, and one bad point among them fails the whole
  // registration (seen: 3 unique pairs of 512 candidate points, where the
  // stereo baseline runs along the face and most dots pair with several).
  if (unique.size() < kMinUniquePairs) {
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
      std::vector<Vec3> from, to;
      double sum_sq = 0;
      for (const PointMatch& m : MutualMatches(grid, best, positions, gate)) {
        from.push_back(positions[m.marker]);
        to.push_back(points[m.point]);
        sum_sq += m.distance * m.distance;
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
  // The expression (file comment, step 2, last): kept where it puts more
  // markers on points than the rigid (and jaw) registration.
  labelling_.rigid_inliers =
      static_cast<int>(MutualMatches(grid, best, positions_, 0.5 * options_.inlier_mm).size());
  if (layout_.expression_basis.cols() > 0 && inliers >= 6) {
    const ExpressedLayout expressed = FitExpressedLayout(positions_, layout_, points, grid, best,
                                                         options_.inlier_mm);
    labelling_.expression_inliers = expressed.inliers;
    spdlog::debug("labelling: {} markers on a point rigidly, {} with the dataset's expression",
                  labelling_.rigid_inliers, expressed.inliers);
    const double fewer = static_cast<double>(std::min(detections[0].size(), detections[1].size()));
    if (expressed.inliers > labelling_.rigid_inliers &&
        expressed.inliers >= kExpressedShareOfDetections * fewer) {
      labelling_.expression = true;
      best = expressed.helmet_from_head;
      positions_ = expressed.positions;
      inliers = expressed.inliers;
      rms = expressed.rms_mm;
    }
  }
  labelling_.helmet_from_head = best;
  labelling_.inliers = inliers;
  labelling_.rms_mm = rms;
  if (inliers < std::max(3, num_markers / 5)) {
    labelling_.reason = fmt::format("registration matched only {} of {} markers{}", inliers,
                                    num_markers, LikelyCause(labelling_, options_.pair_gap_mm));
    return;
  }
  labelling_.ok = true;
}

}  // namespace hmc
