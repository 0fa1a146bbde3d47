#include "tracking/track_fixes.h"

#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "core/error.h"
#include "core/file_util.h"
#include "core/temp_dir.h"

namespace hmc {
namespace {

const std::vector<std::string> kCameras = {"cam0", "cam1"};
const std::vector<std::string> kMarkers = {"brow_l_01", "brow_l_02", "chin_01"};
const std::string kHeader = "frame,camera,marker,action,x,y,to\n";

// Every action read back as written, sorted by frame (file order within
// one), and written again to the same text.
TEST(TrackFixes, ReadsEveryActionAndWritesItBack) {
  TempDir dir;
  const std::string text = kHeader +
                           "7,cam1,chin_01,absent,,,\n"
                           "3,cam0,brow_l_01,rename,10.500,20.250,brow_l_02\n"
                           "3,cam0,,rename,11.000,21.000,chin_01\n"
                           "5,cam1,brow_l_02,unname,,,\n"
                           "9,cam0,brow_l_01,move,1.000,2.000,\n";
  WriteFileAtomic(dir.path() / "f.csv", text);
  const std::vector<TrackFix> fixes = ReadTrackFixesCsv(dir.path() / "f.csv", kCameras, kMarkers);
  ASSERT_EQ(fixes.size(), 5u);
  EXPECT_EQ(fixes[0].frame, 3);
  EXPECT_EQ(fixes[0].to, "brow_l_02");
  EXPECT_TRUE(fixes[0].has_pixel);
  EXPECT_EQ(fixes[0].pixel, Vec2(10.5, 20.25));
  EXPECT_EQ(fixes[1].marker, "");  // file order kept within frame 3
  EXPECT_EQ(fixes[2].action, TrackFixAction::kUnname);
  EXPECT_FALSE(fixes[2].has_pixel);
  EXPECT_EQ(fixes[3].action, TrackFixAction::kAbsent);
  EXPECT_EQ(fixes[4].action, TrackFixAction::kMove);
  EXPECT_EQ(fixes[3].line, 2);
  const std::string sorted = kHeader +
                             "3,cam0,brow_l_01,rename,10.500,20.250,brow_l_02\n"
                             "3,cam0,,rename,11.000,21.000,chin_01\n"
                             "5,cam1,brow_l_02,unname,,,\n"
                             "7,cam1,chin_01,absent,,,\n"
                             "9,cam0,brow_l_01,move,1.000,2.000,\n";
  EXPECT_EQ(TrackFixesCsvText(fixes), sorted);
}

// Each bad row is refused naming the file's line and what is wrong.
TEST(TrackFixes, BadRowsAreRefusedWithTheLineAndWhy) {
  TempDir dir;
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"3,cam0,brow_l_01,swap,,,chin_01", "swap"},
      {"0,cam0,brow_l_01,absent,,,", "frame 0"},
      {"3,cam2,brow_l_01,absent,,,", "cam2"},
      {"3,cam0,brow_l_0l,absent,,,", "did you mean 'brow_l_01'"},
      {"3,cam0,brow_l_01,rename,,,chin_02", "chin_02"},
      {"3,cam0,brow_l_01,rename,,,", "`to`"},
      {"3,cam0,,rename,,,chin_01", "x and y"},
      {"3,cam0,brow_l_01,move,,,", "move needs x and y"},
      {"3,cam0,brow_l_01,move,5,,", "x and y go together"},
      {"3,cam0,,absent,,,", "absent needs the marker"},
      {"3,cam0,brow_l_01,unname,,,chin_01", "rename only"},
  };
  for (const auto& [row, why] : cases) {
    WriteFileAtomic(dir.path() / "bad.csv", kHeader + "1,cam0,chin_01,absent,,,\n" + row + "\n");
    try {
      ReadTrackFixesCsv(dir.path() / "bad.csv", kCameras, kMarkers);
      ADD_FAILURE() << "accepted: " << row;
    } catch (const InputError& e) {
      const std::string message = e.what();
      EXPECT_NE(message.find("bad.csv:3"), std::string::npos) << row << ": " << message;
      EXPECT_NE(message.find(why), std::string::npos) << row << ": " << message;
    }
  }
}

}  // namespace
}  // namespace hmc
