#include "blending/frame_solve.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <utility>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <spdlog/spdlog.h>

namespace hmc {

std::vector<std::pair<int, double>> FrameSolve::Weights(int k) const {
  const BundleSolve& b = bundles[k];
  if (b.global_share == 0.0) return b.weights;
  if (b.global_share == 1.0 && b.weights.empty()) return global_weights;
  // Both sorted by shape: merged.
  std::vector<std::pair<int, double>> sum;
  size_t i = 0, j = 0;
  while (i < global_weights.size() || j < b.weights.size()) {
    if (j == b.weights.size() ||
        (i < global_weights.size() && global_weights[i].first < b.weights[j].first)) {
      sum.emplace_back(global_weights[i].first, b.global_share * global_weights[i].second);
      ++i;
    } else if (i == global_weights.size() || b.weights[j].first < global_weights[i].first) {
      sum.push_back(b.weights[j++]);
    } else {
      const double w = b.global_share * global_weights[i].second + b.weights[j].second;
      if (w != 0.0) sum.emplace_back(global_weights[i].first, w);
      ++i, ++j;
    }
  }
  return sum;
}

std::vector<char> BeginFrame(
    const BundleFrame& bundles, const JawPose& jaw,
    const std::unordered_map<std::string, int>& marker_index, int num_bundles,
    FrameSolve* frame) {
  frame->frame = bundles.frame;
  frame->jaw = jaw;
  frame->bundles.assign(num_bundles, BundleSolve());
  std::vector<char> observed(num_bundles, 0);
  for (const auto& [name, p] : bundles.bundles) {
    const auto it = marker_index.find(name);
    if (it == marker_index.end()) {
      ++frame->unknown_markers;
      continue;
    }
    observed[it->second] = 1;
    frame->bundles[it->second].observed = p;
  }
  return observed;
}

void SetResiduals(const std::vector<SurfacePoint>& sites, const MatX3i& F,
                  const MatX3d& mesh, FrameSolve* frame) {
  for (size_t k = 0; k < frame->bundles.size(); ++k) {
    BundleSolve& b = frame->bundles[k];
    if (!b.Measured()) continue;
    b.residual = (EvaluateSurfacePoint(sites[k], F, mesh) - b.observed).norm();
  }
}

int BundlesNeeded(double min_fraction, int num_bundles) {
  return std::max(
      1, static_cast<int>(std::ceil(min_fraction * num_bundles - 1e-9)));
}

std::string SolveSummary::BriefReport() const {
  return fmt::format(
      "{} frames ({} bad); bundles: {} inside, {} projected (max {:.3f} mm), "
      "{} filled",
      frames, bad_frames, bundles_inside, bundles_projected, max_projection,
      bundles_filled);
}

void SolveSummary::Count(const FrameSolve& frame) {
  for (const BundleSolve& b : frame.bundles) {
    switch (b.status) {
      case BundleSolve::Status::kInside: ++bundles_inside; break;
      case BundleSolve::Status::kProjected:
        ++bundles_projected;
        max_projection = std::max(max_projection, b.distance);
        break;
      case BundleSolve::Status::kFilled: ++bundles_filled; break;
      case BundleSolve::Status::kUnused: break;
    }
  }
}

void SequenceInputOptions::Register(OptionFields* fields) {
  fields->SetGroup("input");
  fields->Add("max_frame_gap", &max_frame_gap,
              "most missing frames in a row between two frames of "
              "bundles.csv; a larger gap is an input error (frames)")
      .AtLeast(0);
  fields->Add("outlier_margin_mm", &outlier_margin_mm,
              "a bundle farther than this outside the box of every position "
              "the actor's dataset gives its marker (the jaw taken out) is "
              "an outlier: flagged, dropped from its frame (mm)")
      .In(0, 1e6);
  fields->Add("jaw_open_deg", &jaw_open_deg,
              "[min, max] of a jaw pose's open_deg; outside: the frame is "
              "flagged bad (degrees)")
      .In(-180, 180);
  fields->Add("jaw_lateral_max_deg", &jaw_lateral_max_deg,
              "largest |lateral_deg| of a jaw pose; beyond: the frame is "
              "flagged bad (degrees)")
      .In(0, 180);
  fields->Add("jaw_protrude_max_mm", &jaw_protrude_max_mm,
              "largest |protrude_mm| of a jaw pose; beyond: the frame is "
              "flagged bad (mm)")
      .In(0, 1000);
  fields->SetGroup("");
}

bool SequenceInputOptions::Check() const {
  CHECK_OPTION_LIMITS();
  CHECK_OPTION_EQ(jaw_open_deg.size(), 2u);
  CHECK_OPTION_LE(jaw_open_deg[0], jaw_open_deg[1]);
  return true;
}

std::string JawPoseRangeError(const JawPose& pose,
                              const SequenceInputOptions& options) {
  if (!(pose.open_deg >= options.jaw_open_deg[0] &&
        pose.open_deg <= options.jaw_open_deg[1])) {
    return fmt::format(
        "jaw pose out of range: open_deg {} outside [{}, {}] "
        "(input.jaw_open_deg)",
        pose.open_deg, options.jaw_open_deg[0], options.jaw_open_deg[1]);
  }
  if (!(std::abs(pose.lateral_deg) <= options.jaw_lateral_max_deg)) {
    return fmt::format(
        "jaw pose out of range: |lateral_deg| {} > {} "
        "(input.jaw_lateral_max_deg)",
        std::abs(pose.lateral_deg), options.jaw_lateral_max_deg);
  }
  if (!(std::abs(pose.protrude_mm) <= options.jaw_protrude_max_mm)) {
    return fmt::format(
        "jaw pose out of range: |protrude_mm| {} > {} "
        "(input.jaw_protrude_max_mm)",
        std::abs(pose.protrude_mm), options.jaw_protrude_max_mm);
  }
  return "";
}

DenseSequence MakeDenseSequence(const std::vector<BundleFrame>& rows,
                                const std::string& bundles_name,
                                const std::vector<JawFrame>* jaw,
                                const std::string& jaw_name,
                                const Actor& actor,
                                const SequenceInputOptions& options) {
  HMC_CHECK(!rows.empty());
  // Frames are labels: a gap is decided on before anything is allocated
  // (64-bit arithmetic, frame numbers span the whole int range).
  for (size_t i = 1; i < rows.size(); ++i) {
    const int64_t missing = static_cast<int64_t>(rows[i].frame) -
                            static_cast<int64_t>(rows[i - 1].frame) - 1;
    if (missing > options.max_frame_gap) {
      ThrowInputError(bundles_name, 0,
                      "frames {} and {} are {} missing frames apart, more "
                      "than input.max_frame_gap = {} (a stray frame number?)",
                      rows[i - 1].frame, rows[i].frame, missing,
                      options.max_frame_gap);
    }
  }
  const int64_t span = static_cast<int64_t>(rows.back().frame) - rows.front().frame + 1;
  if (span > (int64_t{1} << 30)) {
    ThrowInputError(bundles_name, 0, "frames {} to {}: more than 2^30 frames", rows.front().frame,
                    rows.back().frame);
  }
  DenseSequence d;
  d.first_frame = rows.front().frame;
  const int n = static_cast<int>(span);
  d.frames.resize(n);
  d.jaw.resize(n);
  d.outliers.resize(n);
  d.frame_errors.assign(n, "no bundles in this frame");
  for (int i = 0; i < n; ++i) d.frames[i].frame = d.first_frame + i;

  std::set<std::string> known, unknown;
  for (const Marker& marker : actor.markers) known.insert(marker.name);
  for (const BundleFrame& row : rows) {
    const int i = row.frame - d.first_frame;
    d.frames[i] = row;
    d.frame_errors[i].clear();
    for (const auto& [name, p] : row.bundles) {
      if (!known.count(name)) {
        unknown.insert(name);
        ++d.unknown_rows;
      }
    }
  }
  d.unknown_markers.assign(unknown.begin(), unknown.end());
  if (!d.unknown_markers.empty()) {
    spdlog::warn("{}: {} row(s) name {} marker(s) the actor does not have "
                 "(ignored): {}",
                 bundles_name, d.unknown_rows, d.unknown_markers.size(),
                 fmt::join(d.unknown_markers, ", "));
  }
  if (jaw) {
    std::map<int, JawPose> by_frame;
    for (const JawFrame& j : *jaw) by_frame[j.frame] = j.pose;
    for (int i = 0; i < n; ++i) {
      const auto it = by_frame.find(d.frames[i].frame);
      if (it != by_frame.end()) {
        d.jaw[i] = it->second;
        const std::string range = JawPoseRangeError(it->second, options);
        if (!range.empty() && d.frame_errors[i].empty()) {
          d.frame_errors[i] = range + " in " + jaw_name;
          d.jaw[i] = JawPose();  // never skin with it, even a filled frame
        }
      } else if (d.frame_errors[i].empty()) {
        d.frame_errors[i] = "no jaw pose for this frame in " + jaw_name;
      }
    }
  }
  return d;
}

void DropBundlesBeyondReach(const ShapeData& data, double margin_mm,
                            const std::string& bundles_name, DenseSequence* d) {
  const int K = data.num_bundles;
  std::unordered_map<std::string, int> marker_index;
  for (int k = 0; k < K; ++k) marker_index[data.bundle_names[k]] = k;
  // Each site's box over the neutral (zero displacement) and every shape.
  MatX3d lo = MatX3d::Zero(K, 3), hi = MatX3d::Zero(K, 3);
  for (int n = 0; n < data.num_shapes; ++n) {
    const auto block = data.site_displacement.middleRows(static_cast<int64_t>(n) * K, K);
    lo = lo.cwiseMin(block);
    hi = hi.cwiseMax(block);
  }
  lo += data.site_neutral;
  hi += data.site_neutral;
  double farthest_kept = 0;
  std::string first;
  for (size_t i = 0; i < d->frames.size(); ++i) {
    auto& bundles = d->frames[i].bundles;
    for (auto it = bundles.begin(); it != bundles.end();) {
      const auto k = marker_index.find(it->first);
      if (k == marker_index.end()) {  // unknown: counted by MakeDenseSequence
        ++it;
        continue;
      }
      const Vec3 u = UnskinBundle(data, k->second, d->jaw[i], it->second);
      const Vec3 outside = (lo.row(k->second).transpose() - u)
                               .cwiseMax(u - hi.row(k->second).transpose())
                               .cwiseMax(0.0);
      const double distance = outside.norm();
      if (distance <= margin_mm) {
        farthest_kept = std::max(farthest_kept, distance);
        ++it;
        continue;
      }
      if (first.empty()) {
        first = fmt::format("frame {} marker {}, {:.1f} mm out", d->frames[i].frame, it->first,
                            distance);
      }
      d->outliers[i].push_back(it->first);
      ++d->num_outliers;
      it = bundles.erase(it);
    }
  }
  if (d->num_outliers > 0) {
    spdlog::warn(
        "{}: {} bundle(s) beyond their marker's reach (farther than "
        "input.outlier_margin_mm = {} mm outside the box of every position the "
        "actor's dataset gives the marker, the jaw taken out): dropped from "
        "their frames and filled like missing markers; first: {}",
        bundles_name, d->num_outliers, margin_mm, first);
  }
  spdlog::debug("{}: the farthest bundle kept is {:.3f} mm beyond its marker's reach",
                bundles_name, farthest_kept);
}

void FillBadMeshes(const TriMesh& neutral, const JawRig* rig,
                   SolveResult* result) {
  const std::vector<FrameSolve>& frames = result->frames;
  HMC_CHECK(result->meshes.size() == frames.size());
  result->summary.bad_frames = FillBadFrames(
      [&](int f) { return frames[f].ok; },
      [&](int f) {
        return rig ? Skin(*rig, frames[f].jaw, neutral.V) : neutral.V;
      },
      &result->meshes);
  for (const FrameSolve& fs : frames) {
    if (!fs.ok) spdlog::warn("frame {}: skipped: {}", fs.frame, fs.reason);
  }
}

void MeshStream::Good(int f, MatX3d mesh) {
  last_good_ = std::move(mesh);
  any_good_ = true;
  sink_(f, result_->frames[f], last_good_);
}

void MeshStream::Bad(int f) {
  const FrameSolve& frame = result_->frames[f];
  if (any_good_) {
    sink_(f, frame, last_good_);
  } else {
    sink_(f, frame, rig_ ? MatX3d(Skin(*rig_, frame.jaw, neutral_.V)) : neutral_.V);
  }
}

void MeshStream::Finish() {
  int bad = 0;
  for (const FrameSolve& fs : result_->frames) {
    if (fs.ok) continue;
    ++bad;
    spdlog::warn("frame {}: skipped: {}", fs.frame, fs.reason);
  }
  result_->summary.bad_frames = bad;
  last_good_ = MatX3d();
}

void DrainMeshes(const MeshSink& sink, SolveResult* result) {
  HMC_CHECK(result->meshes.size() == result->frames.size());
  for (size_t f = 0; f < result->meshes.size(); ++f) {
    sink(static_cast<int>(f), result->frames[f], result->meshes[f]);
    result->meshes[f] = MatX3d();
  }
  result->meshes.clear();
}

}  // namespace hmc
