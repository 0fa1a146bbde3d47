#include "core/frame_gaps.h"

#include "core/error.h"

namespace hmc {

std::vector<int> InsertMissingFrames(std::vector<BundleFrame>* frames,
                                     const std::filesystem::path& origin) {
  for (size_t i = 1; i < frames->size(); ++i) {
    const int64_t gap =
        static_cast<int64_t>((*frames)[i].frame) - (*frames)[i - 1].frame - 1;
    if (gap > kMaxMissingFrames) {
      ThrowInputError(origin, 0,
                      "frames {} and {} are {} frames apart (at most {} missing frames in a row): a "
                      "stray frame number?",
                      (*frames)[i - 1].frame, (*frames)[i].frame, gap + 1, kMaxMissingFrames + 1);
    }
  }
  std::vector<int> inserted;
  std::vector<BundleFrame> all;
  for (BundleFrame& f : *frames) {
    for (int n = all.empty() ? f.frame : all.back().frame + 1; n < f.frame; ++n) {
      inserted.push_back(n);
      all.push_back({n, {}});
    }
    all.push_back(std::move(f));
  }
  *frames = std::move(all);
  return inserted;
}

}  // namespace hmc
