#include "tracking/track_eval.h"

#include <algorithm>
#include <random>
#include <string>

#include <gtest/gtest.h>

namespace hmc {
namespace {

// A row of ground truth: a dot of `marker` at `pixel` in cam0 of `frame`.
Dot2dTruth Dot(int frame, const std::string& marker, Vec2 pixel, DotDiscState disc,
               double seen) {
  Dot2dTruth d;
  d.frame = frame;
  d.camera = "cam0";
  d.marker = marker;
  d.pixel = pixel;
  d.visible = disc != DotDiscState::kHidden;
  d.disc = disc;
  d.seen = seen;
  if (disc == DotDiscState::kFull) {
    d.has_centroid = true;
    d.centroid = pixel + Vec2(0.1, 0);  // the centroid a little off the point, as on curved skin
  }
  return d;
}

Track2d Row(int frame, const std::string& marker, Vec2 pixel) {
  return Track2d{frame, "cam0", marker, pixel, 1.0};
}

// Random dot layouts 20 px apart and rows of every kind the score tells
// apart: right, on another marker's dot, off its own dot, on a hidden dot,
// for a marker not in the image. Every count is known by construction.
class ScoreTracksSeeds : public ::testing::TestWithParam<int> {};

TEST_P(ScoreTracksSeeds, CountsEveryKindOfRowAsConstructed) {
  std::mt19937 rng(GetParam());
  std::uniform_real_distribution<double> jitter(-0.3, 0.3);
  std::vector<Dot2dTruth> truth;
  std::vector<Track2d> tracks;
  int full = 0, full_named = 0, partial = 0, partial_named = 0, half = 0, half_named = 0;
  int hidden = 0, hidden_rows = 0, other = 0, off = 0, rows = 0;
  std::vector<double> errors;
  for (int frame = 1; frame <= 5; ++frame) {
    for (int i = 0; i < 12; ++i) {
      const std::string name = "m" + std::to_string(i);
      const Vec2 p(100 + 20 * i + jitter(rng), 200 + jitter(rng));
      const int kind = static_cast<int>(rng() % 6);
      const DotDiscState disc = kind < 3 ? DotDiscState::kFull
                                : kind < 5 ? DotDiscState::kPartial
                                           : DotDiscState::kHidden;
      const double seen = disc == DotDiscState::kFull      ? 1.0
                          : disc == DotDiscState::kPartial ? (kind == 3 ? 0.75 : 0.25)
                                                           : 0.0;
      truth.push_back(Dot(frame, name, p, disc, seen));
      full += disc == DotDiscState::kFull;
      partial += disc == DotDiscState::kPartial;
      half += disc == DotDiscState::kPartial && seen >= 0.5;
      hidden += disc == DotDiscState::kHidden;
      const int row = static_cast<int>(rng() % 5);  // 0: none, 1-2: right, 3: off, 4: other's dot
      if (row == 0) continue;
      ++rows;
      full_named += disc == DotDiscState::kFull;
      partial_named += disc == DotDiscState::kPartial;
      half_named += disc == DotDiscState::kPartial && seen >= 0.5;
      hidden_rows += disc == DotDiscState::kHidden;
      const Vec2 own = truth.back().has_centroid ? truth.back().centroid : p;
      if (row <= 2) {
        const Vec2 at = own + Vec2(0.05 * row, 0);
        tracks.push_back(Row(frame, name, at));
        if (disc == DotDiscState::kFull) errors.push_back(0.05 * row);
      } else if (row == 3) {
        tracks.push_back(Row(frame, name, own + Vec2(0, 3.0)));  // 3 px off, nearest to no other
        ++off;
        if (disc == DotDiscState::kFull) errors.push_back(3.0);
      } else {
        // On the next marker's point (20 px to the right): nearer another
        // marker's dot than its own when that one is visible, and in any
        // case more than 2 px off its own.
        tracks.push_back(Row(frame, name, p + Vec2(19.5, 0)));
        if (disc == DotDiscState::kFull) errors.push_back((p + Vec2(19.5, 0) - own).norm());
        // Whether the next marker is visible is only known once it is drawn:
        // decided after the frame (below).
      }
    }
  }
  // The "other's dot" rows: nearer another marker's dot only if that one
  // is visible in the frame; otherwise only off.
  for (const Track2d& t : tracks) {
    const int i = std::stoi(t.marker.substr(1));
    const Dot2dTruth* own = nullptr;
    const Dot2dTruth* next = nullptr;
    for (const Dot2dTruth& d : truth) {
      if (d.frame != t.frame) continue;
      if (d.marker == t.marker) own = &d;
      if (d.marker == "m" + std::to_string(i + 1)) next = &d;
    }
    if ((t.pixel - own->pixel).norm() < 10) continue;  // not an other's-dot row
    if (next != nullptr && next->visible) {
      ++other;
    } else {
      ++off;
    }
  }
  // A row for a marker the truth does not place in the image.
  tracks.push_back(Row(1, "not_in_image", Vec2(5, 5)));
  ++rows;
  ++other;

  const TrackScore s = ScoreTracks(tracks, truth);
  EXPECT_EQ(s.rows, rows);
  EXPECT_EQ(s.full, full);
  EXPECT_EQ(s.full_named, full_named);
  EXPECT_EQ(s.partial, partial);
  EXPECT_EQ(s.partial_named, partial_named);
  EXPECT_EQ(s.partial_half, half);
  EXPECT_EQ(s.partial_half_named, half_named);
  EXPECT_EQ(s.hidden, hidden);
  EXPECT_EQ(s.hidden_rows, hidden_rows);
  EXPECT_EQ(s.wrong_other, other);
  EXPECT_EQ(s.wrong_off, off);
  EXPECT_EQ(s.wrong, other + off);
  size_t per_frame = 0;
  for (const auto& [frame, e] : s.full_errors_by_frame) per_frame += e.size();
  EXPECT_EQ(per_frame, errors.size());
  std::sort(errors.begin(), errors.end());
  ASSERT_FALSE(errors.empty());
  EXPECT_NEAR(s.max_px, errors.back(), 1e-9);
}

INSTANTIATE_TEST_SUITE_P(Seeds, ScoreTracksSeeds, ::testing::Values(1, 2, 3));

TEST(ScoreTracks, WithoutSeenColumnNoPartialIsCountedAsHalfSeen) {
  std::vector<Dot2dTruth> truth = {Dot(1, "a", Vec2(10, 10), DotDiscState::kPartial, -1)};
  const TrackScore s = ScoreTracks({Row(1, "a", Vec2(10, 10))}, truth);
  EXPECT_EQ(s.partial, 1);
  EXPECT_EQ(s.partial_named, 1);
  EXPECT_EQ(s.partial_half, 0);
  EXPECT_EQ(s.wrong, 0);
}

// Whole dots at random view cosines, named or not, with a known offset
// from their rim centroid: every bin's counts and quantiles as constructed,
// and a dot that is not whole (or a file without the column) in none.
TEST(ScoreTracks, BinsWholeDotsByViewCosine) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> cos_of(0.0, 1.0), offset(0.0, 0.5);
  std::vector<Dot2dTruth> truth;
  std::vector<Track2d> rows;
  int64_t views[kNumCosBins] = {}, named[kNumCosBins] = {}, from_015 = 0, named_015 = 0;
  std::vector<double> errors[kNumCosBins];
  for (int i = 0; i < 400; ++i) {
    const std::string name = "m" + std::to_string(i);
    const Vec2 p(20.0 * (i % 20), 20.0 * (i / 20));
    const double c = cos_of(rng);
    Dot2dTruth d = Dot(1, name, p, c >= 0.5 ? DotDiscState::kFull : DotDiscState::kPartial, c);
    d.has_cos = true;
    d.view_cos = c;
    d.whole = i % 7 == 0 ? 0 : 1;
    d.has_whole_centroid = d.whole == 1;
    d.whole_centroid = p + Vec2(0, 0.3);
    truth.push_back(d);
    const bool is_named = i % 3 != 0;
    const double e = offset(rng);
    if (is_named) rows.push_back(Row(1, name, d.whole_centroid + Vec2(e, 0)));
    if (d.whole != 1) continue;
    const int bin = c < 0.15 ? 0 : c < 0.3 ? 1 : c < 0.4 ? 2 : 3;
    ++views[bin];
    from_015 += c >= 0.15;
    if (is_named) {
      ++named[bin];
      named_015 += c >= 0.15;
      errors[bin].push_back(e);
    }
  }
  const TrackScore s = ScoreTracks(rows, truth);
  ASSERT_TRUE(s.has_whole);
  int64_t total = 0;
  for (int b = 0; b < kNumCosBins; ++b) {
    EXPECT_EQ(s.whole_bins[b].views, views[b]) << CosBinName(b);
    EXPECT_EQ(s.whole_bins[b].named, named[b]) << CosBinName(b);
    total += views[b];
    ASSERT_FALSE(errors[b].empty());
    std::sort(errors[b].begin(), errors[b].end());
    EXPECT_GE(s.whole_bins[b].median_px, errors[b].front());
    EXPECT_LE(s.whole_bins[b].p95_px, errors[b].back() + 1e-12);
    EXPECT_LE(s.whole_bins[b].median_px, s.whole_bins[b].p95_px);
  }
  EXPECT_EQ(total, 400 - 58);  // every 7th is not whole
  EXPECT_EQ(s.whole_from_015.views, from_015);
  EXPECT_EQ(s.whole_from_015.named, named_015);
  EXPECT_EQ(s.wrong, 0);  // every row within 0.5 px of its rim centroid
  EXPECT_EQ(CosBinName(0), "0-0.15");
  EXPECT_EQ(CosBinName(3), ">=0.4");
  for (Dot2dTruth& d : truth) d.whole = -1;
  EXPECT_FALSE(ScoreTracks(rows, truth).has_whole);
}

}  // namespace
}  // namespace hmc
