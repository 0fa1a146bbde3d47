#include "synth/tag_render.h"

#include <gtest/gtest.h>

#include "core/error.h"

namespace hmc {
namespace {

TEST(TagPatternTest, BordersAndDistinctCodes) {
  const TagPattern a(0), b(1);
  ASSERT_EQ(a.total_cells(), 10);
  ASSERT_EQ(a.border_cells(), 8);
  const double cell = 1.0 / a.border_cells();
  for (int i = 0; i < 10; ++i) {
    const double u = -0.625 + (i + 0.5) * cell;
    // Outer ring white, next ring black.
    EXPECT_EQ(a.Sample(u, -0.625 + 0.5 * cell), 1);
    EXPECT_EQ(a.Sample(-0.625 + 0.5 * cell, u), 1);
    if (i >= 1 && i <= 8) {
      EXPECT_EQ(a.Sample(u, -0.5 + 0.5 * cell), 0);
      EXPECT_EQ(a.Sample(0.5 - 0.5 * cell, u), 0);
    }
  }
  EXPECT_EQ(a.Sample(0.7, 0), -1);
  int differ = 0;
  for (int r = 0; r < 6; ++r) {
    for (int c = 0; c < 6; ++c) {
      const double x = -0.375 + (c + 0.5) * cell, y = -0.375 + (r + 0.5) * cell;
      differ += a.Sample(x, y) != b.Sample(x, y);
    }
  }
  EXPECT_GE(differ, 11);  // tag36h11: minimum Hamming distance 11
  EXPECT_THROW(TagPattern(100000), InputError);
}

}  // namespace
}  // namespace hmc
