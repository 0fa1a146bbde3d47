// Per-frame data passed between stages as CSV (docs/formats.md):
//   bundles.csv  frame,marker,x,y,z   (mm, head space; a missing marker has
//                                       no row)
//   jaw.csv      frame,open_deg,lateral_deg,protrude_mm
//   head_from_helmet.csv  frame,r00,r01,r02,r10,r11,r12,r20,r21,r22,tx,ty,tz
//                (the rigid transform per frame; rotation row-major, mm)
// Format: docs/formats.md.
#pragma once

#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "core/jaw.h"
#include "core/types.h"

namespace hmc {

struct BundleFrame {
  int frame = 0;
  std::map<std::string, Vec3> bundles;  // marker name -> position (mm)
};

// Frames in increasing order. Throws InputError with file and line on a bad
// header, a malformed row, NaN/Inf, or a marker repeated in one frame.
std::vector<BundleFrame> ReadBundlesCsv(const std::filesystem::path& path);
void WriteBundlesCsv(const std::filesystem::path& path,
                     const std::vector<BundleFrame>& frames);

struct JawFrame {
  int frame = 0;
  JawPose pose;
};
std::vector<JawFrame> ReadJawCsv(const std::filesystem::path& path);
void WriteJawCsv(const std::filesystem::path& path,
                 const std::vector<JawFrame>& frames);

// One rigid transform per frame (head_from_helmet.csv): x_in_head =
// pose * x_in_helmet.
struct PoseFrame {
  int frame = 0;
  Rigid3 pose = Rigid3::Identity();
};
// Throws InputError with file and line on a bad header or row, a repeated
// frame, or a matrix that is not a rotation (|R^T R - I| > 1e-6 or
// det R < 0).
std::vector<PoseFrame> ReadPosesCsv(const std::filesystem::path& path);
void WritePosesCsv(const std::filesystem::path& path,
                   const std::vector<PoseFrame>& frames);

}  // namespace hmc
