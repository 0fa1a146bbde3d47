// What several benchmarks share: the default synthetic actor made once per
// process, a frame of bundles read off a mesh, and the peak resident memory
// counter. Header only: each *_bench.cc is its own program (bench/CMakeLists.txt).
#pragma once

#include <sys/resource.h>

#include <vector>

#include "core/frame_data.h"
#include "core/logging.h"
#include "indexing/shape_data.h"
#include "synth/synth_actor.h"

namespace hmc {

// The default synthetic actor (SynthActorOptions defaults: 51,200 vertices,
// 108 shapes, 155 markers), synthesized on first use with logging quiet.
inline const Actor& DefaultActor() {
  static const Actor actor = [] {
    InitLogging(-1);
    return SynthesizeActor(SynthActorOptions());
  }();
  return actor;
}

// Frame `frame`'s bundles: every site of `data` on the positions `x`
// (V x 3) of the triangles F, named as the actor's markers.
inline BundleFrame BundlesOnMesh(const ShapeData& data, const MatX3i& F,
                                 const MatX3d& x, int frame) {
  BundleFrame b;
  b.frame = frame;
  for (int k = 0; k < data.num_bundles; ++k) {
    b.bundles[data.bundle_names[k]] = EvaluateSurfacePoint(data.sites[k], F, x);
  }
  return b;
}

// The jaw poses of a sequence of jaw frames, in order.
inline std::vector<JawPose> JawPoses(const std::vector<JawFrame>& frames) {
  std::vector<JawPose> poses;
  poses.reserve(frames.size());
  for (const JawFrame& j : frames) poses.push_back(j.pose);
  return poses;
}

// Peak resident memory of the process so far (MB; getrusage maxrss, which
// never decreases: read it per sweep, in order).
inline double PeakRssMb() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_maxrss / 1024.0;  // ru_maxrss is in KiB on Linux
}

}  // namespace hmc
