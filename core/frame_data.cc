#include "core/frame_data.h"

#include <charconv>
#include <cmath>
#include <ostream>
#include <set>
#include <string_view>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "core/error.h"
#include "core/file_util.h"

namespace hmc {
namespace {

// One CSV line split at commas, fields trimmed of surrounding blanks. The
// files we read are machine-written and never quote fields, so quoting is
// not supported (a quote is reported as a malformed field).
std::vector<std::string_view> SplitCsvLine(std::string_view line) {
  std::vector<std::string_view> fields;
  size_t start = 0;
  while (true) {
    const size_t comma = line.find(',', start);
    std::string_view field = line.substr(
        start, comma == std::string_view::npos ? std::string_view::npos
                                               : comma - start);
    while (!field.empty() && (field.front() == ' ' || field.front() == '\t')) {
      field.remove_prefix(1);
    }
    while (!field.empty() && (field.back() == ' ' || field.back() == '\t')) {
      field.remove_suffix(1);
    }
    fields.push_back(field);
    if (comma == std::string_view::npos) break;
    start = comma + 1;
  }
  return fields;
}

// Calls row(fields, line_number) for every non-blank line after the header;
// checks the header first. Accepts \n and \r\n line ends.
template <typename RowFn>
void ForEachCsvRow(const std::filesystem::path& path,
                   const std::vector<std::string>& header, const RowFn& row) {
  const std::string text = ReadFile(path);
  std::string_view rest(text);
  int line_number = 0;
  bool header_seen = false;
  while (!rest.empty()) {
    const size_t end = rest.find('\n');
    std::string_view line = rest.substr(0, end);
    rest.remove_prefix(end == std::string_view::npos ? rest.size() : end + 1);
    ++line_number;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    if (line.find_first_not_of(" \t") == std::string_view::npos) continue;
    const std::vector<std::string_view> fields = SplitCsvLine(line);
    if (!header_seen) {
      bool ok = fields.size() == header.size();
      for (size_t i = 0; ok && i < header.size(); ++i) {
        ok = fields[i] == header[i];
      }
      if (!ok) {
        ThrowInputError(path, line_number, "bad header '{}': expected '{}'",
                        line, fmt::join(header, ","));
      }
      header_seen = true;
      continue;
    }
    if (fields.size() != header.size()) {
      ThrowInputError(path, line_number, "expected {} fields ({}), found {}",
                      header.size(), fmt::join(header, ","), fields.size());
    }
    row(fields, line_number);
  }
  if (!header_seen) {
    ThrowInputError(path, 0, "empty file: expected the header '{}'",
                    fmt::join(header, ","));
  }
}

int ParseInt(std::string_view field, const std::filesystem::path& path,
             int line, const char* what) {
  int value = 0;
  const auto [end, error] =
      std::from_chars(field.data(), field.data() + field.size(), value);
  if (field.empty() || error != std::errc() ||
      end != field.data() + field.size()) {
    ThrowInputError(path, line, "{} '{}' is not an integer", what, field);
  }
  return value;
}

double ParseFinite(std::string_view field, const std::filesystem::path& path,
                   int line, const char* what) {
  double value = 0;
  const auto [end, error] =
      std::from_chars(field.data(), field.data() + field.size(), value);
  if (field.empty() || error != std::errc() ||
      end != field.data() + field.size()) {
    ThrowInputError(path, line, "{} '{}' is not a number", what, field);
  }
  if (!std::isfinite(value)) {
    ThrowInputError(path, line, "{} is {} (must be finite)", what, field);
  }
  return value;
}

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
      [&](const std::vector<std::string_view>& fields, int line) {
        const int frame = ParseInt(fields[0], path, line, "frame");
        const std::string marker(fields[1]);
        if (marker.empty()) ThrowInputError(path, line, "empty marker name");
        Vec3 position;
        for (int axis = 0; axis < 3; ++axis) {
          position[axis] = ParseFinite(fields[2 + axis], path, line,
                                       BundlesHeader()[2 + axis].c_str());
        }
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
                [&](const std::vector<std::string_view>& fields, int line) {
                  JawFrame jaw;
                  jaw.frame = ParseInt(fields[0], path, line, "frame");
                  std::array<double, 3> values;
                  for (int i = 0; i < 3; ++i) {
                    values[i] = ParseFinite(fields[1 + i], path, line,
                                            header[1 + i].c_str());
                  }
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
  const std::vector<std::string>& header = PosesHeader();
  ForEachCsvRow(
      path, header, [&](const std::vector<std::string_view>& fields, int line) {
        PoseFrame pose;
        pose.frame = ParseInt(fields[0], path, line, "frame");
        Mat3 rotation;
        Vec3 translation;
        for (int i = 0; i < 9; ++i) {
          rotation(i / 3, i % 3) =
              ParseFinite(fields[1 + i], path, line, header[1 + i].c_str());
        }
        for (int i = 0; i < 3; ++i) {
          translation[i] =
              ParseFinite(fields[10 + i], path, line, header[10 + i].c_str());
        }
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
