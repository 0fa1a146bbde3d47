#include "core/frame_gaps.h"

#include <algorithm>
#include <random>

#include <gtest/gtest.h>

#include "core/error.h"

namespace hmc {
namespace {

std::vector<BundleFrame> Frames(const std::vector<int>& numbers) {
  std::vector<BundleFrame> frames;
  for (int n : numbers) frames.push_back({n, {{"m", Vec3(n, 0, 0)}}});
  return frames;
}

// Every number between the first and last frame comes back once, in order;
// the frames given keep their bundles, the inserted ones have none.
TEST(FrameGapsTest, MissingNumbersBecomeEmptyFramesInOrder) {
  for (int seed = 1; seed <= 3; ++seed) {
    std::mt19937 rng(seed);
    std::vector<int> numbers;
    for (int n = -5 + seed; n < 60; n += 1 + static_cast<int>(rng() % 4)) numbers.push_back(n);
    std::vector<BundleFrame> frames = Frames(numbers);
    const std::vector<int> inserted = InsertMissingFrames(&frames, "b.csv");
    ASSERT_EQ(frames.size(), static_cast<size_t>(numbers.back() - numbers.front() + 1));
    EXPECT_EQ(inserted.size(), frames.size() - numbers.size());
    size_t k = 0;
    for (size_t i = 0; i < frames.size(); ++i) {
      EXPECT_EQ(frames[i].frame, numbers.front() + static_cast<int>(i));
      const bool given = std::find(numbers.begin(), numbers.end(), frames[i].frame) != numbers.end();
      EXPECT_EQ(frames[i].bundles.size(), given ? 1u : 0u);
      if (!given) {
        ASSERT_LT(k, inserted.size());
        EXPECT_EQ(inserted[k++], frames[i].frame);
      } else {
        EXPECT_EQ(frames[i].bundles.at("m").x(), frames[i].frame);
      }
    }
  }
  std::vector<BundleFrame> none;
  EXPECT_TRUE(InsertMissingFrames(&none, "b.csv").empty());
  std::vector<BundleFrame> contiguous = Frames({4, 5, 6});
  EXPECT_TRUE(InsertMissingFrames(&contiguous, "b.csv").empty());
  EXPECT_EQ(contiguous.size(), 3u);
}

// A stray frame number is an error naming the file, and nothing is inserted.
TEST(FrameGapsTest, AStrayFrameNumberIsAnInputError) {
  std::vector<BundleFrame> frames = Frames({1, 2, 2 + kMaxMissingFrames + 1});
  EXPECT_TRUE(InsertMissingFrames(&frames, "b.csv").size() == kMaxMissingFrames);
  frames = Frames({1, 2, 2000000000});
  try {
    InsertMissingFrames(&frames, "b.csv");
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("b.csv"), std::string::npos) << e.what();
  }
  EXPECT_EQ(frames.size(), 3u);
}

}  // namespace
}  // namespace hmc
