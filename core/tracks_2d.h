// 2D observations of painted dots in the fisheye images (docs/formats.md):
//   tracks_2d.csv  frame,camera,marker,x,y,score
//                  what `hmc track` writes and `hmc triangulate` reads: a row
//                  per named dot per frame and camera (px in the fisheye
//                  image, OpenCV pixel centres; score in [0, 1]).
//   dots_2d.csv    frame,camera,marker,x,y,visible,disc,cx,cy[,seen]
//                  the ground truth of a synthetic shot (`hmc synth shot`;
//                  shots rendered before `seen` existed lack the column).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "core/types.h"

namespace hmc {

struct Track2d {
  int frame = 0;
  std::string camera;  // camera name in calibration.yaml
  std::string marker;  // actor marker name
  Vec2 pixel = Vec2::Zero();  // dot centre (px, fisheye image)
  double score = 1;    // detection quality in [0, 1]
};

// Rows sorted by (frame, camera, marker). Throws InputError with file and
// line on a bad header or row, a non-finite value, a score outside [0, 1],
// or a (frame, camera, marker) given twice.
std::vector<Track2d> ReadTracks2dCsv(const std::filesystem::path& path);
// Writes `tracks` sorted by (frame, camera, marker), atomically; pixels with
// 6 decimals. Throws InputError naming `path` on a name that CSV cannot
// hold or a non-finite value (nothing is written).
void WriteTracks2dCsv(const std::filesystem::path& path,
                      std::vector<Track2d> tracks);

// How much of a painted dot a camera sees (docs/footage.md).
enum class DotDiscState { kHidden, kPartial, kFull };

struct Dot2dTruth {
  int frame = 0;
  std::string camera;
  std::string marker;
  Vec2 pixel = Vec2::Zero();  // exact projection of the marker's point
  bool visible = false;       // the marker's point is seen
  DotDiscState disc = DotDiscState::kHidden;
  bool has_centroid = false;  // `full` dots only
  Vec2 centroid = Vec2::Zero();  // the dot's intensity centroid (px)
  // Fraction of the disc seen, in [0, 1] (docs/formats.md); negative when
  // the file has no `seen` column.
  double seen = -1;
  // The later columns (docs/formats.md), absent from older files: the view
  // cosine at the marker's point (has_cos), whether the whole disc is in
  // view however grazing (`whole`: -1 unknown, 0, 1), and a whole dot's
  // rim centroid (has_whole_centroid; cx, cy for a full dot).
  bool has_cos = false;
  double view_cos = 0;
  int whole = -1;
  bool has_whole_centroid = false;
  Vec2 whole_centroid = Vec2::Zero();
};

// Reads dots_2d.csv in file order. Throws InputError with file and line.
std::vector<Dot2dTruth> ReadDots2dCsv(const std::filesystem::path& path);

}  // namespace hmc
