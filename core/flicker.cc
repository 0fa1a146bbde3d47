#include "core/flicker.h"

#include <cstdint>

#include "core/error.h"
#include "core/parallel.h"

namespace hmc {

FlickerStats ComputeFlicker(const std::vector<MatX3d>& truth,
                            const std::vector<MatX3d>& recon,
                            const std::vector<char>& mask,
                            const std::vector<char>& bad) {
  const int num_frames = static_cast<int>(truth.size());
  if (recon.size() != truth.size()) {
    throw InputError(fmt::format(
        "flicker: {} truth frames but {} reconstructed frames", truth.size(),
        recon.size()));
  }
  if (!bad.empty() && static_cast<int>(bad.size()) != num_frames) {
    throw InputError(fmt::format("flicker: {} bad-frame flags for {} frames",
                                 bad.size(), num_frames));
  }
  FlickerStats stats;
  if (num_frames == 0) return stats;
  const Eigen::Index num_vertices = truth[0].rows();
  for (int t = 0; t < num_frames; ++t) {
    if (truth[t].rows() != num_vertices || recon[t].rows() != num_vertices) {
      throw InputError(fmt::format(
          "flicker: frame {} has {} truth and {} reconstructed vertices, "
          "expected {}",
          t, truth[t].rows(), recon[t].rows(), num_vertices));
    }
  }
  if (!mask.empty() && static_cast<Eigen::Index>(mask.size()) != num_vertices) {
    throw InputError(fmt::format("flicker: mask has {} flags for {} vertices",
                                 mask.size(), num_vertices));
  }
  int64_t num_counted = 0;
  for (Eigen::Index v = 0; v < num_vertices; ++v) {
    if (mask.empty() || mask[v]) ++num_counted;
  }
  auto good = [&](int t) { return bad.empty() || !bad[t]; };

  // Per centre frame: the sum over counted vertices, or -1 if unused.
  std::vector<double> frame_sum(num_frames, -1.0);
  ParallelFor(1, num_frames - 1, [&](int64_t i) {
    const int t = static_cast<int>(i);
    if (!good(t - 1) || !good(t) || !good(t + 1)) return;
    double sum = 0;
    for (Eigen::Index v = 0; v < num_vertices; ++v) {
      if (!mask.empty() && !mask[v]) continue;
      const Eigen::RowVector3d d2 =
          (recon[t + 1].row(v) - truth[t + 1].row(v)) -
          2.0 * (recon[t].row(v) - truth[t].row(v)) +
          (recon[t - 1].row(v) - truth[t - 1].row(v));
      sum += d2.norm();
    }
    frame_sum[t] = sum;
  });
  double total = 0;
  for (int t = 1; t + 1 < num_frames; ++t) {
    if (frame_sum[t] < 0) continue;
    total += frame_sum[t];
    ++stats.frames_used;
  }
  if (stats.frames_used > 0 && num_counted > 0) {
    stats.mean = total / (static_cast<double>(stats.frames_used) *
                          static_cast<double>(num_counted));
  }
  return stats;
}

}  // namespace hmc
