#include "core/frame_data.h"

#include <cmath>
#include <ostream>
#include <set>
#include <string_view>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "core/error.h"
#include "core/file_util.h"
#include "core/text.h"

namespace hmc {
namespace {

// Shortest text that reads back as exactly the same double.
std::string Exact(double value) { return fmt::format("{}", value); }

void RequireFinite(const std::filesystem::path& path, double value, int frame,
                   std::string_view what) {
  if (!std::isfinite(value)) {
    ThrowInputError(path, 0, "cannot write {} {} in frame {}: not finite",
                    what, value, frame);
  }
}

// The readers merge rows by frame number, so a frame listed twice would not
// read back as written.
template <typename Frame>
void RequireDistinctFrames(const std::filesystem::path& path,
                           const std::vector<Frame>& frames) {
  std::set<int> seen;
  for (const Frame& frame : frames) {
    if (!seen.insert(frame.frame).second) {
      ThrowInputError(path, 0, "cannot write: frame {} given twice",
                      frame.frame);
    }
  }
}

const std::vector<std::string>& BundlesHeader() {
  static const std::vector<std::string> header = {"frame", "marker", "x", "y",
                                                  "z"};
  return header;
}

std::vector<std::string> JawHeader() {
  std::vector<std::string> header = {"frame"};
  for (const std::string& name : JawPose::ParameterNames()) {
    header.push_back(name);
  }
  return header;
}

const std::vector<std::string>& PosesHeader() {
  static const std::vector<std::string> header = {
      "frame", "r00", "r01", "r02", "r10", "r11", "r12",
      "r20",   "r21", "r22", "tx",  "ty",  "tz"};
  return header;
}

}  // namespace

std::vector<BundleFrame> ReadBundlesCsv(const std::filesystem::path& path) {
  std::map<int, BundleFrame> frames;
  // Where each (frame, marker) was first seen, to name both lines of a
  // duplicate.
  std::map<std::pair<int, std::string>, int> first_line;
  ForEachCsvRow(
      path, BundlesHeader(),
      [&](const CsvRow& row) {
        const int line = row.line();
        const int frame = row.Int(0);
        const std::string& marker = row.NonEmpty(1);
        const Vec3 position(row.Finite(2), row.Finite(3), row.Finite(4));
        const auto [it, inserted] =
            first_line.emplace(std::make_pair(frame, marker), line);
        if (!inserted) {
          ThrowInputError(path, line,
                          "marker '{}' repeated in frame {} (first on line {})",
                          marker, frame, it->second);
        }
        BundleFrame& bundle_frame = frames[frame];
        bundle_frame.frame = frame;
        bundle_frame.bundles.emplace(marker, position);
      });
  std::vector<BundleFrame> result;
  result.reserve(frames.size());
  for (auto& [frame, bundle_frame] : frames) {
    result.push_back(std::move(bundle_frame));
  }
  return result;
}

void WriteBundlesCsv(const std::filesystem::path& path,
                     const std::vector<BundleFrame>& frames) {
  // Validate everything before the write starts, so a bad value fails with
  // a clear message and leaves no file behind.
  RequireDistinctFrames(path, frames);
  for (const BundleFrame& frame : frames) {
    for (const auto& [marker, position] : frame.bundles) {
      if (marker.empty() ||
          marker.find_first_of(",\"\r\n") != std::string::npos ||
          marker.front() == ' ' || marker.back() == ' ' ||
          marker.front() == '\t' || marker.back() == '\t') {
        ThrowInputError(path, 0,
                        "marker name '{}' cannot be written to CSV (empty, "
                        "has a comma, quote, line break or surrounding "
                        "blanks)",
                        marker);
      }
      for (int axis = 0; axis < 3; ++axis) {
        RequireFinite(path, position[axis], frame.frame,
                      "position of marker " + marker);
      }
    }
  }
  WriteFileAtomic(path, [&](std::ostream& out) {
    out << fmt::format("{}\n", fmt::join(BundlesHeader(), ","));
    for (const BundleFrame& frame : frames) {
      for (const auto& [marker, position] : frame.bundles) {
        out << frame.frame << ',' << marker << ',' << Exact(position.x())
            << ',' << Exact(position.y()) << ',' << Exact(position.z())
            << '\n';
      }
    }
  });
}

std::vector<JawFrame> ReadJawCsv(const std::filesystem::path& path) {
  std::map<int, std::pair<JawFrame, int>> frames;  // frame -> (pose, line)
  const std::vector<std::string> header = JawHeader();
  ForEachCsvRow(path, header,
                [&](const CsvRow& row) {
                  const int line = row.line();
                  JawFrame jaw;
                  jaw.frame = row.Int(0);
                  const std::array<double, 3> values = {
                      row.Finite(1), row.Finite(2), row.Finite(3)};
                  jaw.pose = JawPose::FromArray(values);
                  const auto [it, inserted] =
                      frames.emplace(jaw.frame, std::make_pair(jaw, line));
                  if (!inserted) {
                    ThrowInputError(path, line,
                                    "frame {} repeated (first on line {})",
                                    jaw.frame, it->second.second);
                  }
                });
  std::vector<JawFrame> result;
  result.reserve(frames.size());
  for (const auto& [frame, jaw_and_line] : frames) {
    result.push_back(jaw_and_line.first);
  }
  return result;
}

void WriteJawCsv(const std::filesystem::path& path,
                 const std::vector<JawFrame>& frames) {
  RequireDistinctFrames(path, frames);
  for (const JawFrame& frame : frames) {
    const std::array<double, 3> values = frame.pose.ToArray();
    for (int i = 0; i < 3; ++i) {
      RequireFinite(path, values[i], frame.frame,
                    JawPose::ParameterNames()[i]);
    }
  }
  WriteFileAtomic(path, [&](std::ostream& out) {
    out << fmt::format("{}\n", fmt::join(JawHeader(), ","));
    for (const JawFrame& frame : frames) {
      const std::array<double, 3> values = frame.pose.ToArray();
      out << frame.frame << ',' << Exact(values[0]) << ',' << Exact(values[1])
          << ',' << Exact(values[2]) << '\n';
    }
  });
}

std::vector<PoseFrame> ReadPosesCsv(const std::filesystem::path& path) {
  std::map<int, std::pair<PoseFrame, int>> frames;  // frame -> (pose, line)
  ForEachCsvRow(path, PosesHeader(), [&](const CsvRow& row) {
    const int line = row.line();
    PoseFrame pose;
    pose.frame = row.Int(0);
    Mat3 rotation;
    for (int i = 0; i < 9; ++i) rotation(i / 3, i % 3) = row.Finite(1 + i);
    const Vec3 translation(row.Finite(10), row.Finite(11), row.Finite(12));
    const double orthogonality =
        (rotation.transpose() * rotation - Mat3::Identity()).norm();
    if (orthogonality > 1e-6 || rotation.determinant() < 0) {
      ThrowInputError(path, line,
                      "not a rotation: |R^T R - I| = {:.3g}, det R = {:.6f}",
                      orthogonality, rotation.determinant());
    }
    pose.pose.linear() = rotation;
    pose.pose.translation() = translation;
    const auto [it, inserted] =
        frames.emplace(pose.frame, std::make_pair(pose, line));
    if (!inserted) {
      ThrowInputError(path, line, "frame {} repeated (first on line {})",
                      pose.frame, it->second.second);
    }
  });
  std::vector<PoseFrame> result;
  result.reserve(frames.size());
  for (const auto& [frame, pose_and_line] : frames) {
    result.push_back(pose_and_line.first);
  }
  return result;
}

void WritePosesCsv(const std::filesystem::path& path,
                   const std::vector<PoseFrame>& frames) {
  RequireDistinctFrames(path, frames);
  for (const PoseFrame& frame : frames) {
    if (!frame.pose.matrix().allFinite()) {
      ThrowInputError(path, 0, "cannot write the pose of frame {}: not finite",
                      frame.frame);
    }
  }
  WriteFileAtomic(path, [&](std::ostream& out) {
    out << fmt::format("{}\n", fmt::join(PosesHeader(), ","));
    for (const PoseFrame& frame : frames) {
      const Mat3 r = frame.pose.linear();
      const Vec3 t = frame.pose.translation();
      out << frame.frame;
      for (int i = 0; i < 9; ++i) out << ',' << Exact(r(i / 3, i % 3));
      for (int i = 0; i < 3; ++i) out << ',' << Exact(t[i]);
      out << '\n';
    }
  });
}

}  // namespace hmc
