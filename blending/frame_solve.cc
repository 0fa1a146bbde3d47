#include "blending/frame_solve.h"

#include <algorithm>
#include <cmath>
#include <map>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

namespace hmc {

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

DenseSequence MakeDenseSequence(const std::vector<BundleFrame>& rows,
                                const std::vector<JawFrame>* jaw,
                                const std::string& jaw_name) {
  HMC_CHECK(!rows.empty());
  DenseSequence d;
  d.first_frame = rows.front().frame;
  const int n = rows.back().frame - d.first_frame + 1;
  d.frames.resize(n);
  d.jaw.resize(n);
  d.frame_errors.assign(n, "no bundles in this frame");
  for (int i = 0; i < n; ++i) d.frames[i].frame = d.first_frame + i;
  for (const BundleFrame& row : rows) {
    d.frames[row.frame - d.first_frame] = row;
    d.frame_errors[row.frame - d.first_frame].clear();
  }
  if (jaw) {
    std::map<int, JawPose> by_frame;
    for (const JawFrame& j : *jaw) by_frame[j.frame] = j.pose;
    for (int i = 0; i < n; ++i) {
      const auto it = by_frame.find(d.frames[i].frame);
      if (it != by_frame.end()) {
        d.jaw[i] = it->second;
      } else if (d.frame_errors[i].empty()) {
        d.frame_errors[i] = "no jaw pose for this frame in " + jaw_name;
      }
    }
  }
  return d;
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

}  // namespace hmc
