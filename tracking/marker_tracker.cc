#include "tracking/marker_tracker.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <unordered_map>

#include <Eigen/Geometry>
#include <opencv2/video/tracking.hpp>
#include <spdlog/spdlog.h>

#include "core/parallel.h"
#include "tracking/assignment.h"
#include "tracking/marker_geometry.h"
#include "tracking/stereo_rays.h"

namespace hmc {

void MarkerTrackerOptions::Register(OptionFields* fields) {
  fields->Add("pair_gap_mm", &pair_gap_mm,
              "stereo pairing: largest ray closest-approach distance (mm)")
      .Above(0);
  fields->Add("max_offset_mm", &max_offset_mm, "head offset from rest the labelling must cover (mm)")
      .AtLeast(0);
  fields->Add("max_offset_deg", &max_offset_deg,
              "head rotation from rest the labelling must cover (deg)")
      .AtLeast(0).Below(60);
  fields->Add("triple_tolerance_mm", &triple_tolerance_mm,
              "RANSAC: pairwise distance agreement of a triple (mm)")
      .Above(0);
  fields->Add("inlier_mm", &inlier_mm, "registration inlier distance (mm)").Above(0);
  fields->Add("ransac_samples", &ransac_samples, "RANSAC triples of points tried").AtLeast(1);
  fields->Add("name_gate", &name_gate,
              "naming gate (fraction of the distance to the nearest other dot)")
      .Above(0).Below(0.5);
  fields->Add("track_gate", &track_gate,
              "tracking gate (fraction of the distance to the nearest other dot)")
      .Above(0).Below(0.5);
  fields->Add("reacquire_gate", &reacquire_gate,
              "re-acquisition gate (fraction of the nearest-dot distance)")
      .Above(0).Below(0.5);
  fields->Add("max_gate_px", &max_gate_px, "cap of every gate (px)").Above(0);
  fields->Add("ambiguity_ratio", &ambiguity_ratio,
              "second-nearest detection at least this much farther")
      .AtLeast(1);
  fields->Add("epipolar_gap_mm", &epipolar_gap_mm,
              "stereo swap check: largest ray gap of a named pair (mm)")
      .Above(0);
  fields->Add("neighbours", &neighbours, "layout neighbours whose residuals correct a projection")
      .AtLeast(1);
  fields->Add("flow_window", &flow_window, "Lucas-Kanade window (dot diameters)").In(1, 10);
  fields->Add("jaw_reach_deg", &jaw_reach_deg,
              "largest change of the jaw opening between two frames that is followed (deg)")
      .In(1, 45);
  fields->Add("flow_check_px", &flow_check_px,
              "largest forward-backward flow disagreement (px)")
      .Above(0);
  fields->Add("search_gate", &search_gate,
              "search for an expected dot: radius (fraction of the nearest-dot distance; 0 = off)")
      .AtLeast(0)
      .Below(0.5);
  fields->Add("lost_frames", &lost_frames,
              "a dot missing this many frames in a row where both cameras should see it, after "
              "as many named in both, is lost (0 = never)")
      .AtLeast(0);
}

bool MarkerTrackerOptions::Check() const {
  CHECK_OPTION_LIMITS();
  return true;
}

namespace {

// The per-frame jaw search's reach in the two small motions of the jaw
// (the opening's is an option): a lateral swing and a protrusion change
// within a frame are a few degrees and millimetres at most.
constexpr double kJawLateralReachDeg = 3;
constexpr double kJawProtrudeReachMm = 2;

// A dot seen within 60 degrees of its normal shows its whole disc (the
// synthetic shots' "full" dots, docs/formats.md): where such a dot is
// expected and no detection is, none is painted.
constexpr double kSquarelyCos = 0.5;
// A marker this close to the neutral's border (the lips' opening) may be
// half hidden by the other lip: its dot is not told missing. On the
// synthetic actor the lip markers lie 1.2-4.3 mm from it, all others
// 8.5 mm or more.
constexpr double kBesideOpeningMm = 5;
// The search for expected dots looks for markers seen at a view cosine of
// at least this (issue 44 asks for whole dots down to 0.15; the neutral's
// normal is not the posed face's), placed by at least this many named
// neighbours (else by the flow, if they were tracked into the frame).
constexpr double kSearchMinCos = 0.1;
constexpr int kSearchMinNeighbours = 2;
// The flow and the named neighbours place an unnamed dot within a few
// tenths of a pixel (measured: median 0.1-0.3 px): a dark blob further
// than half a dot diameter from that place is not the dot expected (on a
// lid or a lip beside it, the search finds their edge with the dot).
constexpr double kSearchMaxRadius = 0.5;
// Rounds of the search: the dots a round names place their neighbours for
// the next (a row of thin dots at the forehead's edge, missed together).
constexpr int kSearchRounds = 3;

int FlowWindow(double dot_size_px, double window) {
  return std::max(7, static_cast<int>(std::lround(window * dot_size_px)) | 1);
}

std::vector<cv::Mat> FlowPyramid(const cv::Mat& image, int window) {
  std::vector<cv::Mat> pyramid;
  if (image.empty()) return pyramid;
  cv::Mat grey8 = image;
  if (image.depth() == CV_16U) image.convertTo(grey8, CV_8U, 1.0 / 257);
  cv::buildOpticalFlowPyramid(grey8, pyramid, cv::Size(window, window), 3);
  return pyramid;
}

}  // namespace

MarkerTracker::MarkerTracker(const HelmetRig& rig, const MarkerLayout& layout,
                             const MarkerTrackerOptions& options, const DotDetectorOptions& detect)
    : rig_(rig), layout_(layout), options_(options), detect_(detect) {
  state_.assign(rig_.cameras.size(), std::vector<DotState>(layout_.names.size()));
}

void MarkerTracker::Match(int /*camera*/, const std::vector<DotDetection>& detections,
                          const std::vector<Vec2>& prediction, const std::vector<char>& predicted,
                          const std::vector<double>& gate_fraction, bool require_unambiguous_all,
                          std::vector<int>* detection_of) const {
  const int num_markers = static_cast<int>(prediction.size());
  const int num_detections = static_cast<int>(detections.size());
  // Spacing: distance to the nearest other prediction.
  std::vector<double> gates(num_markers, 1e-9);
  for (int k = 0; k < num_markers; ++k) {
    if (!predicted[k]) continue;
    double nearest = std::numeric_limits<double>::infinity();
    for (int j = 0; j < num_markers; ++j) {
      if (j != k && predicted[j]) nearest = std::min(nearest, (prediction[j] - prediction[k]).norm());
    }
    gates[k] = std::min(options_.max_gate_px, gate_fraction[k] * nearest);
  }
  std::vector<AssignmentEdge> edges;
  for (int k = 0; k < num_markers; ++k) {
    if (!predicted[k] || (*detection_of)[k] >= 0) continue;
    for (int d = 0; d < num_detections; ++d) {
      const double dist = (detections[d].pixel - prediction[k]).norm();
      if (dist < gates[k]) edges.push_back({k, d, dist});
    }
  }
  // Detections already taken (earlier rounds) are not offered again.
  std::vector<char> taken(num_detections, 0);
  for (int k = 0; k < num_markers; ++k) {
    if ((*detection_of)[k] >= 0) taken[(*detection_of)[k]] = 1;
  }
  edges.erase(std::remove_if(edges.begin(), edges.end(),
                             [&](const AssignmentEdge& e) { return taken[e.col] != 0; }),
              edges.end());
  const std::vector<int> col = SolveGatedAssignment(num_markers, num_detections, edges, gates);
  for (int k = 0; k < num_markers; ++k) {
    if (col[k] < 0) continue;
    const bool check = require_unambiguous_all || gate_fraction[k] < options_.track_gate;
    if (check) {
      const double d1 = (detections[col[k]].pixel - prediction[k]).norm();
      double d2 = std::numeric_limits<double>::infinity();
      for (int d = 0; d < num_detections; ++d) {
        if (d != col[k]) d2 = std::min(d2, (detections[d].pixel - prediction[k]).norm());
      }
      if (d2 <= options_.ambiguity_ratio * d1 || d2 < gates[k]) continue;
    }
    (*detection_of)[k] = col[k];
  }
}

void MarkerTracker::StereoCheck(const std::vector<std::vector<DotDetection>>& detections,
                                std::vector<std::vector<int>>* detection_of,
                                std::vector<CameraFrameTracks>* out) const {
  if (detection_of->size() < 2) return;
  for (size_t k = 0; k < layout_.names.size(); ++k) {
    const int d0 = (*detection_of)[0][k], d1 = (*detection_of)[1][k];
    if (d0 < 0 || d1 < 0) continue;
    const RayApproach a = ClosestApproach(PixelRay(rig_.cameras[0], detections[0][d0].pixel),
                                          PixelRay(rig_.cameras[1], detections[1][d1].pixel));
    if (a.ok && a.gap <= options_.epipolar_gap_mm) continue;
    (*detection_of)[0][k] = -1;
    (*detection_of)[1][k] = -1;
    ++(*out)[0].swaps_caught;
    ++(*out)[1].swaps_caught;
  }
}

MarkerTracker::LayoutView MarkerTracker::ViewLayout(int c,
                                                    const std::vector<Vec3>& positions) const {
  const int num_markers = static_cast<int>(layout_.names.size());
  const HelmetCamera& hc = rig_.cameras[c];
  const Rigid3 cam_from_head = hc.cam_from_helmet * helmet_from_head_;
  LayoutView view;
  view.facing.assign(num_markers, 0);
  view.squarely.assign(num_markers, 0);
  view.projection.assign(num_markers, Vec2::Zero());
  view.cos.assign(num_markers, 0);
  view.normal_dir.assign(num_markers, Vec2(1, 0));
  for (int k = 0; k < num_markers; ++k) {
    const Vec3 p = cam_from_head * positions[k];
    const Vec3 n = cam_from_head.linear() * layout_.normals[k];
    Vec2 u;
    if (!hc.camera.Project(p, &u) || !hc.camera.IsInImage(u)) continue;
    view.cos[k] = -n.dot(p.normalized());
    view.facing[k] = view.cos[k] > 0.1;
    view.squarely[k] = view.cos[k] > kSquarelyCos;
    view.projection[k] = u;
    // The normal's image direction: the short axis of the dot's ellipse.
    Vec2 tip;
    if (hc.camera.Project(p + n, &tip) && (tip - u).norm() > 1e-9) {
      view.normal_dir[k] = (tip - u).normalized();
    }
  }
  return view;
}

int MarkerTracker::CorrectedProjection(int k, const LayoutView& view,
                                       const std::vector<DotDetection>& detections,
                                       const std::vector<int>& detection_of,
                                       Vec2* prediction) const {
  Vec2 sum = Vec2::Zero();
  int count = 0;
  for (int j : layout_.neighbours[k]) {
    if (detection_of[j] < 0 || !view.facing[j]) continue;
    sum += detections[detection_of[j]].pixel - view.projection[j];
    ++count;
  }
  *prediction = view.projection[k] + (count > 0 ? Vec2(sum / count) : Vec2::Zero());
  return count;
}

std::vector<int> MarkerTracker::SearchExpected(
    const std::vector<cv::Mat>& images, const std::vector<std::vector<Vec2>>& tracked,
    const std::vector<std::vector<char>>& has_tracked,
    std::vector<std::vector<DotDetection>>* detections,
    std::vector<std::vector<int>>* detection_of) const {
  const int num_cameras = static_cast<int>(images.size());
  const int num_markers = static_cast<int>(layout_.names.size());
  std::vector<int> named(num_cameras, 0);
  if (options_.search_gate <= 0) return named;
  // Per camera and marker, the dot found where it was expected.
  std::vector<std::vector<std::optional<DotDetection>>> found(
      num_cameras, std::vector<std::optional<DotDetection>>(num_markers));
  ParallelFor(0, num_cameras, [&](int64_t camera) {
    const int c = static_cast<int>(camera);
    if (images[c].empty()) return;
    const LayoutView view = ViewLayout(c, positions_);
    const std::vector<DotDetection>& dets = (*detections)[c];
    const std::vector<int>& of = (*detection_of)[c];
    // Where every marker's dot is (named) or is expected.
    std::vector<Vec2> prediction(num_markers, Vec2::Zero());
    std::vector<char> predicted(num_markers, 0);
    for (int k = 0; k < num_markers; ++k) {
      if (of[k] >= 0) {
        prediction[k] = dets[of[k]].pixel;
        predicted[k] = 1;
      } else if (view.facing[k]) {
        predicted[k] =
            CorrectedProjection(k, view, dets, of, &prediction[k]) >= kSearchMinNeighbours;
        if (!predicted[k] && has_tracked[c][k]) {
          prediction[k] = tracked[c][k];
          predicted[k] = 1;
        }
      }
    }
    for (int k = 0; k < num_markers; ++k) {
      if (of[k] >= 0 || !predicted[k] || view.cos[k] < kSearchMinCos) continue;
      // The spacing counts every marker whose dot may be there: where it is
      // expected, else its projection (a thin neighbour missed too).
      double nearest = std::numeric_limits<double>::infinity();
      for (int j = 0; j < num_markers; ++j) {
        if (j == k || !(predicted[j] || view.cos[j] > 0)) continue;
        const Vec2& at = predicted[j] ? prediction[j] : view.projection[j];
        nearest = std::min(nearest, (at - prediction[k]).norm());
      }
      ExpectedDot expected;
      expected.pixel = prediction[k];
      expected.radius_px = std::min({options_.max_gate_px, options_.search_gate * nearest,
                                     kSearchMaxRadius * dot_size_px_[c]});
      expected.axis_ratio = view.cos[k];
      expected.short_axis = view.normal_dir[k];
      // A detection there already had its chance in the gated matching.
      if (std::any_of(dets.begin(), dets.end(), [&](const DotDetection& d) {
            return (d.pixel - expected.pixel).norm() < expected.radius_px;
          })) {
        continue;
      }
      found[c][k] = DetectDotNear(images[c], detect_, dot_size_px_[c], expected);
    }
  });
  // A dot found is named only where another camera sees the marker on its
  // ray (named there, or found there too): a dark speck where a dot is
  // expected, or a neighbour's dot, seldom lies on the marker's ray.
  for (int k = 0; k < num_markers; ++k) {
    for (int c = 0; c < num_cameras; ++c) {
      if (!found[c][k]) continue;
      bool supported = false;
      for (int o = 0; o < num_cameras && !supported; ++o) {
        if (o == c) continue;
        const int d = (*detection_of)[o][k];
        const bool other_named = d >= 0 && d < static_cast<int>((*detections)[o].size());
        if (!other_named && !found[o][k]) continue;
        const Vec2 other = found[o][k] ? found[o][k]->pixel : (*detections)[o][d].pixel;
        const RayApproach a = ClosestApproach(PixelRay(rig_.cameras[c], found[c][k]->pixel),
                                              PixelRay(rig_.cameras[o], other));
        supported = a.ok && a.gap <= options_.epipolar_gap_mm;
      }
      if (!supported) continue;
      (*detections)[c].push_back(*found[c][k]);
      (*detection_of)[c][k] = static_cast<int>((*detections)[c].size()) - 1;
      ++named[c];
    }
  }
  return named;
}

void MarkerTracker::SearchInRounds(const std::vector<cv::Mat>& images,
                                   const std::vector<std::vector<Vec2>>& tracked,
                                   const std::vector<std::vector<char>>& has_tracked,
                                   std::vector<std::vector<DotDetection>>* detections,
                                   std::vector<std::vector<int>>* detection_of,
                                   std::vector<CameraFrameTracks>* out) const {
  for (int round = 0; round < kSearchRounds; ++round) {
    const std::vector<int> searched =
        SearchExpected(images, tracked, has_tracked, detections, detection_of);
    int any = 0;
    for (size_t c = 0; c < searched.size(); ++c) {
      (*out)[c].searched += searched[c];
      any += searched[c];
    }
    if (any == 0) break;
  }
}

void MarkerTracker::NameFromLayout(int c, const std::vector<Vec3>& positions,
                                   const std::vector<DotDetection>& detections,
                                   double gate_fraction, bool allow_uncorrected,
                                   std::vector<int>* detection_of,
                                   std::vector<int>* vacant) const {
  const int num_markers = static_cast<int>(layout_.names.size());
  const LayoutView view = ViewLayout(c, positions);
  const std::vector<char>& facing = view.facing;
  const std::vector<char>& squarely = view.squarely;
  const std::vector<Vec2>& projection = view.projection;
  const std::vector<double> fraction(num_markers, gate_fraction);
  std::vector<Vec2> prediction(num_markers, Vec2::Zero());
  std::vector<char> corrected(num_markers, 0);
  for (int round = 0; round < 4; ++round) {
    std::fill(prediction.begin(), prediction.end(), Vec2::Zero());
    std::fill(corrected.begin(), corrected.end(), 0);
    std::vector<char> predicted(num_markers, 0);
    int before = 0;
    for (int k = 0; k < num_markers; ++k) {
      if ((*detection_of)[k] >= 0) {
        // Named: where its dot is (it only shapes the others' gates).
        prediction[k] = detections[(*detection_of)[k]].pixel;
        predicted[k] = 1;
        ++before;
        continue;
      }
      if (!facing[k]) continue;
      const int count = CorrectedProjection(k, view, detections, *detection_of, &prediction[k]);
      if (count == 0 && !(allow_uncorrected && round == 0)) continue;
      predicted[k] = 1;
      corrected[k] = count > 0;
    }
    Match(c, detections, prediction, predicted, fraction, true, detection_of);
    const int after = static_cast<int>(
        std::count_if(detection_of->begin(), detection_of->end(), [](int d) { return d >= 0; }));
    if (after == before) break;
  }
  if (vacant == nullptr) return;
  // A marker that faces the camera squarely, placed by its named
  // neighbours, with no unnamed detection nearer its place than the nearest
  // other marker is: no dot is painted there. (A dot that is there but
  // stays unnamed -- ambiguous, off its prediction -- is not; a marker
  // hidden from the camera does not face it or has no named neighbours;
  // one beside the lips' opening may be half hidden by the other lip and
  // never detected. track_shot.cc reports markers never found.)
  std::vector<char> named(detections.size(), 0);
  for (int d : *detection_of) {
    if (d >= 0) named[d] = 1;
  }
  for (int k = 0; k < num_markers; ++k) {
    if ((*detection_of)[k] >= 0 || !squarely[k] || !corrected[k] ||
        layout_.border_mm[k] < kBesideOpeningMm) {
      continue;
    }
    double spacing = std::numeric_limits<double>::infinity();
    for (int j = 0; j < num_markers; ++j) {
      if (j != k && facing[j]) spacing = std::min(spacing, (projection[j] - projection[k]).norm());
    }
    bool occupied = false;
    for (size_t d = 0; d < detections.size(); ++d) {
      occupied = occupied || (!named[d] && (detections[d].pixel - prediction[k]).norm() < spacing);
    }
    if (!occupied) vacant->push_back(k);
  }
}

bool MarkerTracker::MissingWhereSeen(int k, const LayoutView& view,
                                     const std::vector<DotDetection>& detections,
                                     const std::vector<int>& detection_of,
                                     const std::vector<char>& named) const {
  if (view.cos[k] < kSearchMinCos) return false;
  Vec2 place;
  if (CorrectedProjection(k, view, detections, detection_of, &place) < kSearchMinNeighbours) {
    return false;
  }
  double spacing = std::numeric_limits<double>::infinity();
  for (size_t j = 0; j < view.cos.size(); ++j) {
    if (static_cast<int>(j) != k && view.cos[j] > 0) {
      spacing = std::min(spacing, (view.projection[j] - view.projection[k]).norm());
    }
  }
  const double gate = std::min(options_.max_gate_px, options_.name_gate * spacing);
  for (size_t d = 0; d < detections.size(); ++d) {
    if (!named[d] && (detections[d].pixel - place).norm() < gate) return false;
  }
  return true;
}

void MarkerTracker::UpdateLost(const std::vector<std::vector<DotDetection>>& detections,
                               const std::vector<bool>& present,
                               std::vector<std::vector<int>>* detection_of,
                               std::vector<CameraFrameTracks>* out) {
  const int num_cameras = static_cast<int>(detections.size());
  const int num_markers = static_cast<int>(layout_.names.size());
  if (options_.lost_frames <= 0 || num_cameras < 2) return;
  std::vector<LayoutView> views(num_cameras);
  std::vector<std::vector<char>> named(num_cameras);
  for (int c = 0; c < num_cameras; ++c) {
    if (!present[c]) continue;
    views[c] = ViewLayout(c, positions_);
    named[c].assign(detections[c].size(), 0);
    for (int d : (*detection_of)[c]) {
      if (d >= 0) named[c][d] = 1;
    }
  }
  for (int k = 0; k < num_markers; ++k) {
    // Named in both cameras, or missing in every camera (one that sees the
    // dot at a grazing angle or beside the lips' opening may just miss it).
    bool both = true, missing = layout_.border_mm[k] >= kBesideOpeningMm;
    for (int c = 0; c < num_cameras; ++c) {
      const bool has = present[c] && (*detection_of)[c][k] >= 0;
      both = both && has;
      missing = missing && present[c] && !has && views[c].cos[k] > kSquarelyCos &&
                MissingWhereSeen(k, views[c], detections[c], (*detection_of)[c], named[c]);
    }
    if (both) {
      // Named in both cameras (their rays meet: the stereo check and the
      // search saw to it): the dot is there.
      ++stereo_frames_[k];
      missing_frames_[k] = 0;
      lost_since_[k] = -1;
      continue;
    }
    if (!missing) {
      missing_frames_[k] = 0;
    } else {
      if (missing_frames_[k]++ == 0) missing_since_[k] = frame_;
      if (lost_since_[k] < 0 && missing_frames_[k] >= options_.lost_frames &&
          stereo_frames_[k] >= options_.lost_frames) {
        lost_since_[k] = missing_since_[k];
      }
    }
    if (lost_since_[k] < 0) continue;
    for (int c = 0; c < num_cameras; ++c) {
      if (!present[c] || (*detection_of)[c][k] < 0) continue;
      (*detection_of)[c][k] = -1;
      ++(*out)[c].lost_dropped;
    }
  }
}

void MarkerTracker::UpdateHeadPose(const std::vector<std::vector<DotDetection>>& detections,
                                   const std::vector<std::vector<int>>& detection_of) {
  if (detection_of.size() < 2) return;
  std::vector<Vec3> from, to;
  std::vector<int> jaw_markers;  // markers the jaw moves (weight > 0.5), named in both
  std::vector<Vec3> jaw_points;
  for (size_t k = 0; k < layout_.names.size(); ++k) {
    const int d0 = detection_of[0][k], d1 = detection_of[1][k];
    if (d0 < 0 || d1 < 0) continue;
    const RayApproach a = ClosestApproach(PixelRay(rig_.cameras[0], detections[0][d0].pixel),
                                          PixelRay(rig_.cameras[1], detections[1][d1].pixel));
    if (!a.ok) continue;
    from.push_back(positions_[k]);
    to.push_back(a.midpoint);
    if (!layout_.jaw_weights.empty() && layout_.jaw_weights[k] > 0.5) {
      jaw_markers.push_back(static_cast<int>(k));
      jaw_points.push_back(a.midpoint);
    }
  }
  // Trimmed rigid fit: the expression moves some markers far from neutral.
  for (int iteration = 0; iteration < 3 && from.size() >= 6; ++iteration) {
    const Rigid3 t = FitRigid(from, to);
    std::vector<double> residual(from.size());
    for (size_t i = 0; i < from.size(); ++i) residual[i] = (t * from[i] - to[i]).norm();
    std::vector<double> sorted = residual;
    std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
    const double keep = std::max(options_.inlier_mm, 2 * sorted[sorted.size() / 2]);
    std::vector<Vec3> f2, t2;
    for (size_t i = 0; i < from.size(); ++i) {
      if (residual[i] <= keep) {
        f2.push_back(from[i]);
        t2.push_back(to[i]);
      }
    }
    helmet_from_head_ = t;
    if (f2.size() == from.size()) break;
    from.swap(f2);
    to.swap(t2);
  }
  if (layout_.jaw_weights.empty()) return;
  // The jaw near the previous frame's (file comment, Tracking): each
  // jaw-moved marker's distance to its own triangulated point when it is
  // named in both cameras, else to the nearest stereo candidate of any two
  // detections (a lost chin dot is still a candidate, so the jaw follows a
  // mouth that opens faster than the tracks), truncated at inlier_mm. A
  // 1-unit grid within the reach of one frame's motion, then a 0.25-unit
  // grid within +-1, inside the dataset's range.
  const Rigid3 head_from_helmet = helmet_from_head_.inverse();
  for (Vec3& p : jaw_points) p = head_from_helmet * p;
  StereoPairs pairs = PairDetections(rig_, detections, options_.pair_gap_mm);
  for (Vec3& p : pairs.points) p = head_from_helmet * p;
  const PointGrid grid(pairs.points, options_.inlier_mm);
  std::vector<int> own(layout_.names.size(), -1);
  for (size_t i = 0; i < jaw_markers.size(); ++i) own[jaw_markers[i]] = static_cast<int>(i);
  std::vector<int> moving;
  for (size_t k = 0; k < layout_.names.size(); ++k) {
    if (layout_.jaw_weights[k] > 0.5) moving.push_back(static_cast<int>(k));
  }
  const double cap = options_.inlier_mm * options_.inlier_mm;
  auto cost = [&](const JawPose& pose, int* on_point) {
    const Rigid3 t = layout_.jaw_rig.Transform(pose);
    double sum = 0;
    *on_point = 0;
    for (int k : moving) {
      const Vec3 q = SkinPoint(t, layout_.positions[k], layout_.jaw_weights[k]);
      double d2 = cap;
      if (own[k] >= 0) {
        d2 = std::min(cap, (q - jaw_points[own[k]]).squaredNorm());
      } else {
        double d = 0;
        if (grid.Nearest(q, options_.inlier_mm, &d) >= 0) d2 = d * d;
      }
      if (d2 < cap) ++*on_point;
      sum += d2;
    }
    return sum;
  };
  JawPose best = jaw_;
  int on_point = 0;
  double best_cost = cost(best, &on_point);
  int best_on_point = on_point;
  const std::array<double, 3> reach = {options_.jaw_reach_deg, kJawLateralReachDeg,
                                       kJawProtrudeReachMm};
  for (const auto& [scale, step] : {std::pair<double, double>{1, 1}, {0, 0.25}}) {
    const std::array<double, 3> centre = best.ToArray();
    std::array<double, 3> lo{}, hi{};
    for (int i = 0; i < 3; ++i) {
      const double r = scale > 0 ? reach[i] : 1.0;
      lo[i] = std::max(layout_.jaw_lower[i], centre[i] - r);
      hi[i] = std::min(layout_.jaw_upper[i], centre[i] + r);
    }
    ForEachJawPose(lo, hi, step, [&](const JawPose& pose) {
      const double value = cost(pose, &on_point);
      if (value < best_cost) {
        best = pose;
        best_cost = value;
        best_on_point = on_point;
      }
    });
  }
  if (best_on_point < 4) return;  // too few jaw markers seen to tell
  jaw_ = best;
  positions_ = layout_.PosedPositions(jaw_);
}

std::vector<CameraFrameTracks> MarkerTracker::Start(
    const std::vector<std::vector<DotDetection>>& blind, const std::vector<cv::Mat>& images,
    const std::vector<double>& dot_size_px, const std::vector<std::vector<TrackerFix>>* fixes,
    std::vector<FixOutcome>* outcome) {
  // The blind detector's dots, then those the search for expected dots
  // adds.
  std::vector<std::vector<DotDetection>> detections = blind;
  const int num_cameras = static_cast<int>(rig_.cameras.size());
  const int num_markers = static_cast<int>(layout_.names.size());
  std::vector<CameraFrameTracks> out(num_cameras);
  state_.assign(num_cameras, std::vector<DotState>(num_markers));
  absent_.assign(num_cameras, std::vector<char>(num_markers, 0));
  barred_.assign(num_cameras, {});
  confused_.assign(num_cameras, {});
  frame_ = 0;
  stereo_frames_.assign(num_markers, 0);
  missing_frames_.assign(num_markers, 0);
  missing_since_.assign(num_markers, -1);
  lost_since_.assign(num_markers, -1);
  dot_size_px_ = dot_size_px;
  pyramid_.assign(num_cameras, {});
  for (int c = 0; c < num_cameras; ++c) {
    pyramid_[c] = FlowPyramid(images[c], FlowWindow(dot_size_px_[c], options_.flow_window));
  }
  Register(detections);
  if (!labelling_.ok) return out;
  std::vector<std::vector<int>> detection_of(num_cameras, std::vector<int>(num_markers, -1));
  std::vector<std::vector<Vec2>> projection(num_cameras, std::vector<Vec2>(num_markers));
  helmet_from_head_ = labelling_.helmet_from_head;
  for (int c = 0; c < num_cameras; ++c) {
    NameFromLayout(c, positions_, detections[c], options_.name_gate, true,
                   &detection_of[c], &out[c].vacant);
  }
  StereoCheck(detections, &detection_of, &out);
  SearchInRounds(images,
                 std::vector<std::vector<Vec2>>(num_cameras, std::vector<Vec2>(num_markers)),
                 std::vector<std::vector<char>>(num_cameras, std::vector<char>(num_markers, 0)),
                 &detections, &detection_of, &out);
  UpdateLost(detections, std::vector<bool>(num_cameras, true), &detection_of, &out);
  // The review's fixes last, over every naming step (docs/review.md).
  std::vector<std::vector<DotDetection>> fixed;
  const std::vector<std::vector<DotDetection>>& dots =
      ApplyFrameFixes(detections, std::vector<bool>(num_cameras, true), fixes,
                      std::vector<std::vector<int>>(num_cameras), outcome, &fixed, &detection_of);
  for (int c = 0; c < num_cameras; ++c) {
    out[c].detections = static_cast<int>(blind[c].size());
    for (int k = 0; k < num_markers; ++k) {
      const int d = detection_of[c][k];
      if (d < 0) continue;
      DotState& s = state_[c][k];
      s.status = Status::kTracked;
      s.has_position = true;
      s.position = dots[c][d].pixel;
      s.velocity.setZero();
      out[c].marker.push_back(k);
      out[c].pixel.push_back(dots[c][d].pixel);
      out[c].score.push_back(dots[c][d].score);
    }
    out[c].unnamed =
        out[c].detections - (static_cast<int>(out[c].marker.size()) - out[c].searched);
  }
  return out;
}

std::vector<CameraFrameTracks> MarkerTracker::Step(
    const std::vector<std::vector<DotDetection>>& blind, const std::vector<cv::Mat>& images,
    const std::vector<std::vector<TrackerFix>>* fixes, std::vector<FixOutcome>* outcome) {
  const int num_cameras = static_cast<int>(rig_.cameras.size());
  const int num_markers = static_cast<int>(layout_.names.size());
  // The blind detector's dots, then those the search for expected dots
  // adds.
  std::vector<std::vector<DotDetection>> detections = blind;
  // Per camera, the flow's prediction of each dot tracked until now.
  std::vector<std::vector<Vec2>> flow_prediction(num_cameras,
                                                 std::vector<Vec2>(num_markers, Vec2::Zero()));
  std::vector<std::vector<char>> flow_predicted(num_cameras, std::vector<char>(num_markers, 0));
  std::vector<CameraFrameTracks> out(num_cameras);
  std::vector<std::vector<int>> detection_of(num_cameras, std::vector<int>(num_markers, -1));
  std::vector<bool> present(num_cameras);
  for (int c = 0; c < num_cameras; ++c) present[c] = !images[c].empty();
  std::vector<std::vector<int>> barred(num_cameras);  // the barred dots' detections
  // The cameras are independent until the stereo check: each one's flow
  // and matching touch only its own state, side by side.
  ParallelFor(0, num_cameras, [&](int64_t camera) {
    const int c = static_cast<int>(camera);
    if (!present[c]) {
      out[c].skipped = true;
      pyramid_[c].clear();
      barred_[c].clear();  // a dot is followed only from frame to frame
      return;
    }
    const int window = FlowWindow(dot_size_px_[c], options_.flow_window);
    std::vector<cv::Mat> pyramid = FlowPyramid(images[c], window);
    // Flow of the tracked dots from the previous frame, checked backwards.
    std::vector<int> flowed;
    std::vector<cv::Point2f> from, to, back;
    if (!pyramid_[c].empty()) {
      for (int k = 0; k < num_markers; ++k) {
        const DotState& s = state_[c][k];
        if (s.status != Status::kTracked) continue;
        flowed.push_back(k);
        from.emplace_back(static_cast<float>(s.position.x()), static_cast<float>(s.position.y()));
        to.emplace_back(static_cast<float>(s.position.x() + s.velocity.x()),
                        static_cast<float>(s.position.y() + s.velocity.y()));
      }
    }
    std::vector<char> flow_ok(num_markers, 0);
    std::vector<Vec2> flow_to(num_markers);
    if (!flowed.empty()) {
      std::vector<uchar> status, back_status;
      std::vector<float> error, back_error;
      const cv::TermCriteria term(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 20, 0.01);
      cv::calcOpticalFlowPyrLK(pyramid_[c], pyramid, from, to, status, error,
                               cv::Size(window, window), 3, term, cv::OPTFLOW_USE_INITIAL_FLOW);
      back = from;
      cv::calcOpticalFlowPyrLK(pyramid, pyramid_[c], to, back, back_status, back_error,
                               cv::Size(window, window), 3, term, cv::OPTFLOW_USE_INITIAL_FLOW);
      for (size_t i = 0; i < flowed.size(); ++i) {
        const double disagreement = std::hypot(back[i].x - from[i].x, back[i].y - from[i].y);
        if (status[i] && back_status[i] && disagreement <= options_.flow_check_px) {
          flow_ok[flowed[i]] = 1;
          flow_to[flowed[i]] = Vec2(to[i].x, to[i].y);
        }
      }
    }
    barred[c] = FollowBarred(c, pyramid, detections[c]);
    pyramid_[c] = std::move(pyramid);
    std::vector<Vec2> prediction(num_markers);
    std::vector<char> predicted(num_markers, 0);
    std::vector<double> fraction(num_markers, options_.track_gate);
    for (int k = 0; k < num_markers; ++k) {
      const DotState& s = state_[c][k];
      if (!s.has_position) continue;
      if (s.status != Status::kTracked) continue;
      predicted[k] = 1;
      prediction[k] = flow_ok[k] ? flow_to[k] : Vec2(s.position + s.velocity);
      flow_prediction[c][k] = flow_to[k];
      flow_predicted[c][k] = flow_ok[k];
    }
    Match(c, detections[c], prediction, predicted, fraction, false, &detection_of[c]);
  });
  StereoCheck(detections, &detection_of, &out);
  // Re-acquisition: the lost and never-seen dots from the layout under the
  // current head pose, corrected by their named neighbours.
  UpdateHeadPose(detections, detection_of);
  for (int c = 0; c < num_cameras; ++c) {
    if (present[c]) {
      NameFromLayout(c, positions_, detections[c], options_.reacquire_gate, false,
                     &detection_of[c], &out[c].vacant);
    }
  }
  StereoCheck(detections, &detection_of, &out);
  SearchInRounds(images, flow_prediction, flow_predicted, &detections, &detection_of, &out);
  ++frame_;
  UpdateLost(detections, present, &detection_of, &out);
  std::vector<std::vector<DotDetection>> fixed;
  const std::vector<std::vector<DotDetection>>& dots =
      ApplyFrameFixes(detections, present, fixes, barred, outcome, &fixed, &detection_of);
  for (int c = 0; c < num_cameras; ++c) {
    if (!present[c]) continue;
    out[c].detections = static_cast<int>(blind[c].size());
    for (int k = 0; k < num_markers; ++k) {
      DotState& s = state_[c][k];
      const int d = detection_of[c][k];
      if (d >= 0) {
        const Vec2 p = dots[c][d].pixel;
        if (s.status == Status::kTracked) {
          s.velocity = p - s.position;
        } else {
          s.velocity.setZero();
          ++out[c].reacquired;
        }
        s.status = Status::kTracked;
        s.has_position = true;
        s.position = p;
        out[c].marker.push_back(k);
        out[c].pixel.push_back(p);
        out[c].score.push_back(dots[c][d].score);
      } else if (s.status == Status::kTracked) {
        s.status = Status::kLost;
        s.velocity.setZero();
        ++out[c].lost;
      }
    }
    out[c].unnamed =
        out[c].detections - (static_cast<int>(out[c].marker.size()) - out[c].searched);
  }
  return out;
}

int MarkerTracker::FixedDot(int c, const TrackerFix& fix, const std::vector<DotDetection>& detections,
                            const std::vector<int>& detection_of) const {
  if (fix.has_pixel) {
    // Within the dot: a move's point may lie beside a neighbour's dot (a
    // partly hidden dot the detector missed), which it must not take.
    const double gate = std::max(3.0, 0.5 * dot_size_px_[c]);
    int best = -1;
    double best_d = gate;
    for (size_t d = 0; d < detections.size(); ++d) {
      const double dist = (detections[d].pixel - fix.pixel).norm();
      if (dist <= best_d) {
        best_d = dist;
        best = static_cast<int>(d);
      }
    }
    if (best >= 0 || fix.action == TrackFixAction::kMove) return best;
  }
  return fix.marker >= 0 ? detection_of[fix.marker] : -1;
}

void MarkerTracker::ResolveConfusions(int c, const std::vector<DotDetection>& detections,
                                      std::vector<int>* detection_of) const {
  std::optional<LayoutView> view;
  for (const auto& [a, b] : confused_[c]) {
    const int d = (*detection_of)[a];
    if (d < 0 || (*detection_of)[b] >= 0 || absent_[c][b]) continue;
    if (!view) view = ViewLayout(c, positions_);
    std::vector<int> others = *detection_of;
    others[a] = -1;
    Vec2 at_a, at_b;
    CorrectedProjection(a, *view, detections, others, &at_a);
    CorrectedProjection(b, *view, detections, others, &at_b);
    const Vec2 p = detections[d].pixel;
    if ((p - at_b).norm() < (p - at_a).norm()) {
      (*detection_of)[a] = -1;
      (*detection_of)[b] = d;
    }
  }
}

std::vector<int> MarkerTracker::FollowBarred(int c, const std::vector<cv::Mat>& pyramid,
                                             const std::vector<DotDetection>& detections) const {
  const std::vector<Vec2>& from_px = barred_[c];
  std::vector<Vec2> predicted = from_px;
  if (!from_px.empty() && !pyramid_[c].empty()) {
    const int window = FlowWindow(dot_size_px_[c], options_.flow_window);
    std::vector<cv::Point2f> from, to;
    for (const Vec2& p : from_px) from.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()));
    to = from;
    std::vector<uchar> status;
    std::vector<float> error;
    const cv::TermCriteria term(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 20, 0.01);
    cv::calcOpticalFlowPyrLK(pyramid_[c], pyramid, from, to, status, error, cv::Size(window, window),
                             3, term, cv::OPTFLOW_USE_INITIAL_FLOW);
    for (size_t i = 0; i < from.size(); ++i) {
      if (status[i]) predicted[i] = Vec2(to[i].x, to[i].y);
    }
  }
  std::vector<int> found(from_px.size(), -1);
  const double gate = 0.5 * dot_size_px_[c];
  for (size_t i = 0; i < predicted.size(); ++i) {
    double best = gate;
    for (size_t d = 0; d < detections.size(); ++d) {
      const double dist = (detections[d].pixel - predicted[i]).norm();
      if (dist <= best) {
        best = dist;
        found[i] = static_cast<int>(d);
      }
    }
  }
  return found;
}

const std::vector<std::vector<DotDetection>>& MarkerTracker::ApplyFrameFixes(
    const std::vector<std::vector<DotDetection>>& detections, const std::vector<bool>& present,
    const std::vector<std::vector<TrackerFix>>* fixes, const std::vector<std::vector<int>>& barred,
    std::vector<FixOutcome>* outcome, std::vector<std::vector<DotDetection>>* storage,
    std::vector<std::vector<int>>* detection_of) {
  const int num_cameras = static_cast<int>(detections.size());
  if (outcome) outcome->assign(num_cameras, {});
  const std::vector<TrackerFix> none;
  *storage = detections;
  for (int c = 0; c < num_cameras; ++c) {
    if (!present[c]) {  // the camera's image is missing: its fixes found no dot
      for (size_t i = 0; outcome && fixes && i < (*fixes)[c].size(); ++i) {
        (*outcome)[c].unmatched.push_back(static_cast<int>(i));
      }
      continue;
    }
    const FixOutcome o = ApplyFixes(c, fixes ? (*fixes)[c] : none, barred[c], &(*storage)[c],
                                    &(*detection_of)[c]);
    if (outcome) (*outcome)[c] = o;
  }
  return *storage;
}

FixOutcome MarkerTracker::ApplyFixes(int c, const std::vector<TrackerFix>& fixes,
                                     const std::vector<int>& barred,
                                     std::vector<DotDetection>* detections, std::vector<int>* detection_of) {
  FixOutcome outcome;
  // The dots barred from here on (detection indices), the barred ones
  // still found first.
  std::vector<int> bar;
  for (int d : barred) {
    if (d >= 0 && std::find(bar.begin(), bar.end(), d) == bar.end()) bar.push_back(d);
  }
  auto unname_dot = [&](int d) {
    for (int& held : *detection_of) {
      if (held == d) held = -1;
    }
  };
  auto give = [&](int marker, int d) {
    unname_dot(d);  // whoever held the dot loses it
    (*detection_of)[marker] = d;
    absent_[c][marker] = 0;
    bar.erase(std::remove(bar.begin(), bar.end(), d), bar.end());  // a fix names it again
  };
  for (int d : bar) unname_dot(d);
  ResolveConfusions(c, *detections, detection_of);
  for (size_t i = 0; i < fixes.size(); ++i) {
    const TrackerFix& fix = fixes[i];
    int d = fix.action == TrackFixAction::kAbsent ? -1 : FixedDot(c, fix, *detections, *detection_of);
    switch (fix.action) {
      case TrackFixAction::kRename:
        if (d >= 0) {
          for (int k = 0; k < static_cast<int>(detection_of->size()); ++k) {
            const std::pair<int, int> pair(k, fix.to);
            if ((*detection_of)[k] == d && k != fix.to &&
                std::find(confused_[c].begin(), confused_[c].end(), pair) == confused_[c].end()) {
              confused_[c].push_back(pair);
            }
          }
          give(fix.to, d);
        }
        break;
      case TrackFixAction::kUnname:
        if (d >= 0) {
          unname_dot(d);
          if (std::find(bar.begin(), bar.end(), d) == bar.end()) bar.push_back(d);
        }
        break;
      case TrackFixAction::kAbsent:
        absent_[c][fix.marker] = 1;
        d = 0;  // always applies
        break;
      case TrackFixAction::kMove:
        if (d < 0) {
          DotDetection added;
          added.pixel = fix.pixel;
          added.score = 1;
          detections->push_back(added);
          d = static_cast<int>(detections->size()) - 1;
        }
        give(fix.marker, d);
        break;
    }
    if (d >= 0) {
      ++outcome.applied;
    } else {
      outcome.unmatched.push_back(static_cast<int>(i));
    }
  }
  for (size_t k = 0; k < detection_of->size(); ++k) {
    if (absent_[c][k]) (*detection_of)[k] = -1;
  }
  barred_[c].clear();
  for (int d : bar) barred_[c].push_back((*detections)[d].pixel);
  return outcome;
}

}  // namespace hmc
