// Frames lost upstream stay frames. A frame that one stage could not
// produce (a corrupt video frame gives no bundles) is missing from the next
// stage's input file; without this it would vanish from every later stage
// instead of being flagged there (docs/reliability.md, promise 2).
#pragma once

#include <algorithm>
#include <filesystem>
#include <vector>

#include "core/frame_data.h"

namespace hmc {

// The most frame numbers in a row that may be missing between two frames
// of a stage's input (the solve's input.max_frame_gap default): a longer
// gap is a stray frame number, not lost frames.
constexpr int kMaxMissingFrames = 1000;

// Inserts an empty frame (no bundles) for every number missing between
// the first and the last frame of `frames` (increasing, as ReadBundlesCsv
// returns them) and returns the inserted numbers, in order. A run of more
// than kMaxMissingFrames missing numbers is an InputError naming `origin`,
// decided before anything is inserted.
std::vector<int> InsertMissingFrames(std::vector<BundleFrame>* frames,
                                     const std::filesystem::path& origin);

// What a stage's record of an inserted frame says.
constexpr const char* kMissingFrameReason =
    "no bundles: the frame is missing from the input (lost in an earlier stage)";

// Sets the reason of the stage's records (with `frame`, `ok`, `reason`)
// of the frames InsertMissingFrames inserted, which the stage could not fit.
template <typename Record>
void MarkMissingFrames(const std::vector<int>& inserted, std::vector<Record>* records) {
  for (Record& r : *records) {
    if (!r.ok && std::binary_search(inserted.begin(), inserted.end(), r.frame)) {
      r.reason = kMissingFrameReason;
    }
  }
}

}  // namespace hmc
