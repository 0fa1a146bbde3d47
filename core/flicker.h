// Temporal metric for `hmc eval` and `hmc experiment`: flicker, how much the
// reconstruction error jitters from frame to frame.
//
// With e(t) = recon(t) - truth(t) per vertex, flicker is the mean over
// vertices and frames of the norm of the second time difference
//   |e(t+1) - 2 e(t) + e(t-1)|   (mm/frame^2).
// A per-frame position error alone cannot tell a steady offset (which a
// viewer barely notices) from an error that changes every frame (which reads
// as buzzing skin). The second difference is zero for any error that is
// constant or drifts linearly in time, so flicker isolates the part of the
// error that jumps; the first difference would also charge a slow, smooth
// drift.
#pragma once

#include <vector>

#include "core/types.h"

namespace hmc {

struct FlickerStats {
  double mean = 0;      // mm/frame^2; 0 when no frame could be used
  int frames_used = 0;  // centre frames t whose triplet t-1, t, t+1 was used
};

// truth, recon: T frames of V x 3 positions (mm), same T and V.
// mask: V flags, non-zero = vertex counted (empty = all vertices).
// bad: T flags, non-zero = frame unusable (empty = none); a bad frame breaks
// every triplet through it.
// Returns the mean over the vertices in mask and over the frames t with
// t-1, t and t+1 all good of |e(t+1) - 2 e(t) + e(t-1)|, e = recon - truth.
// Throws InputError if the sizes disagree. Deterministic for any thread
// count (per-frame partial sums added in frame order).
FlickerStats ComputeFlicker(const std::vector<MatX3d>& truth,
                            const std::vector<MatX3d>& recon,
                            const std::vector<char>& mask,
                            const std::vector<char>& bad);

}  // namespace hmc
