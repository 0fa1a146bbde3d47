#include "core/tracks_2d.h"

#include <random>

#include <gtest/gtest.h>

#include "core/error.h"
#include "core/file_util.h"
#include "core/temp_dir.h"

namespace hmc {
namespace {

TEST(Tracks2dTest, RoundTripSortsAndKeepsSixDecimals) {
  TempDir dir;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> px(0, 1280);
  std::vector<Track2d> tracks;
  for (int frame : {3, 1, 2}) {
    for (const char* camera : {"cam1", "cam0"}) {
      for (const char* marker : {"lip_l", "brow_r", "chin"}) {
        tracks.push_back({frame, camera, marker, Vec2(px(rng), px(rng)), 0.5});
      }
    }
  }
  WriteTracks2dCsv(dir.path() / "t.csv", tracks);
  const std::vector<Track2d> back = ReadTracks2dCsv(dir.path() / "t.csv");
  ASSERT_EQ(back.size(), tracks.size());
  for (size_t i = 1; i < back.size(); ++i) {
    EXPECT_LE(std::tie(back[i - 1].frame, back[i - 1].camera, back[i - 1].marker),
              std::tie(back[i].frame, back[i].camera, back[i].marker));
  }
  for (const Track2d& t : tracks) {
    const auto it = std::find_if(back.begin(), back.end(), [&](const Track2d& b) {
      return b.frame == t.frame && b.camera == t.camera && b.marker == t.marker;
    });
    ASSERT_NE(it, back.end());
    EXPECT_NEAR((it->pixel - t.pixel).norm(), 0, 1e-6);
    EXPECT_EQ(it->score, 0.5);
  }
}

TEST(Tracks2dTest, RefusesBadRowsWithTheLine) {
  TempDir dir;
  const auto message = [&](const std::string& text) {
    WriteFileAtomic(dir.path() / "t.csv", text);
    try {
      ReadTracks2dCsv(dir.path() / "t.csv");
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  const std::string h = "frame,camera,marker,x,y,score\n";
  EXPECT_NE(message(h + "1,cam0,a,1,2,1\n1,cam0,a,3,4,1\n").find(":3"),
            std::string::npos);
  EXPECT_NE(message(h + "1,cam0,a,1,2,1.5\n").find("outside"), std::string::npos);
  EXPECT_NE(message(h + "1,,a,1,2,1\n").find("empty camera"), std::string::npos);
  EXPECT_NE(message(h + "1,cam0,a,nan,2,1\n").find("finite"), std::string::npos);
  EXPECT_NE(message("frame,camera,marker,x,y\n").find("bad header"),
            std::string::npos);
}

TEST(Tracks2dTest, ReadsShotGroundTruthDots) {
  TempDir dir;
  WriteFileAtomic(dir.path() / "d.csv",
                  "frame,camera,marker,x,y,visible,disc,cx,cy\n"
                  "1,cam0,a,10.5,20.25,1,full,10.6,20.2\n"
                  "1,cam0,b,11,21,1,partial,,\n"
                  "1,cam1,a,12,22,0,hidden,,\n");
  const std::vector<Dot2dTruth> dots = ReadDots2dCsv(dir.path() / "d.csv");
  ASSERT_EQ(dots.size(), 3u);
  EXPECT_EQ(dots[0].disc, DotDiscState::kFull);
  EXPECT_TRUE(dots[0].has_centroid);
  EXPECT_DOUBLE_EQ(dots[0].centroid.x(), 10.6);
  EXPECT_EQ(dots[1].disc, DotDiscState::kPartial);
  EXPECT_FALSE(dots[1].has_centroid);
  EXPECT_FALSE(dots[2].visible);
  EXPECT_EQ(dots[2].disc, DotDiscState::kHidden);
  EXPECT_LT(dots[0].seen, 0);  // a file from before the `seen` column
}

TEST(Tracks2dTest, ReadsTheSeenFractionAndRejectsOneOutOfRange) {
  TempDir dir;
  const std::string header = "frame,camera,marker,x,y,visible,disc,cx,cy,seen\n";
  WriteFileAtomic(dir.path() / "d.csv", header +
                                            "1,cam0,a,10.5,20.25,1,full,10.6,20.2,1.000\n"
                                            "1,cam0,b,11,21,1,partial,,,0.375\n");
  const std::vector<Dot2dTruth> dots = ReadDots2dCsv(dir.path() / "d.csv");
  ASSERT_EQ(dots.size(), 2u);
  EXPECT_DOUBLE_EQ(dots[0].seen, 1.0);
  EXPECT_DOUBLE_EQ(dots[1].seen, 0.375);
  WriteFileAtomic(dir.path() / "bad.csv", header + "1,cam0,b,11,21,1,partial,,,1.5\n");
  try {
    ReadDots2dCsv(dir.path() / "bad.csv");
    FAIL() << "a seen fraction of 1.5 was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("bad.csv:2"), std::string::npos) << e.what();
  }
  // A row with a field too few for its header is refused.
  WriteFileAtomic(dir.path() / "short.csv", header + "1,cam0,b,11,21,1,partial,,\n");
  EXPECT_THROW(ReadDots2dCsv(dir.path() / "short.csv"), InputError);
}

TEST(Tracks2dTest, ReadsTheViewCosineAndWholeDotsAndRejectsBadOnes) {
  TempDir dir;
  const std::string header = "frame,camera,marker,x,y,visible,disc,cx,cy,seen,cos,whole,wcx,wcy\n";
  WriteFileAtomic(dir.path() / "d.csv",
                  header + "1,cam0,a,10.5,20.25,1,full,10.6,20.2,0.9,0.95,1,10.6,20.2\n"
                           "1,cam0,b,11,21,1,partial,,,0.2,0.21,1,11.3,21.1\n"
                           "1,cam0,c,12,22,1,partial,,,0.1,0.4,0,,\n");
  const std::vector<Dot2dTruth> dots = ReadDots2dCsv(dir.path() / "d.csv");
  ASSERT_EQ(dots.size(), 3u);
  EXPECT_TRUE(dots[1].has_cos);
  EXPECT_DOUBLE_EQ(dots[1].view_cos, 0.21);
  EXPECT_EQ(dots[1].whole, 1);
  EXPECT_TRUE(dots[1].has_whole_centroid);
  EXPECT_FALSE(dots[1].has_centroid);
  EXPECT_DOUBLE_EQ(dots[1].whole_centroid.x(), 11.3);
  EXPECT_EQ(dots[2].whole, 0);
  EXPECT_FALSE(dots[2].has_whole_centroid);
  // Older files: no cos, `whole` unknown.
  WriteFileAtomic(dir.path() / "old.csv", "frame,camera,marker,x,y,visible,disc,cx,cy,seen\n"
                                          "1,cam0,a,10.5,20.25,1,full,10.6,20.2,1.000\n");
  const std::vector<Dot2dTruth> old = ReadDots2dCsv(dir.path() / "old.csv");
  ASSERT_EQ(old.size(), 1u);
  EXPECT_FALSE(old[0].has_cos);
  EXPECT_EQ(old[0].whole, -1);
  for (const char* bad : {"1,cam0,b,11,21,1,partial,,,0.2,1.5,1,11,21\n",
                          "1,cam0,b,11,21,1,partial,,,0.2,0.2,2,11,21\n"}) {
    WriteFileAtomic(dir.path() / "bad.csv", header + bad);
    try {
      ReadDots2dCsv(dir.path() / "bad.csv");
      FAIL() << "accepted " << bad;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("bad.csv:2"), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace hmc
