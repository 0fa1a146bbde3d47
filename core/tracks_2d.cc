#include "core/tracks_2d.h"

#include <algorithm>
#include <cmath>
#include <ostream>
#include <tuple>

#include <fmt/format.h>

#include "core/error.h"
#include "core/file_util.h"
#include "core/text.h"

namespace hmc {
namespace {

bool ByFrameCameraMarker(const Track2d& a, const Track2d& b) {
  return std::tie(a.frame, a.camera, a.marker) <
         std::tie(b.frame, b.camera, b.marker);
}

bool WritableName(const std::string& name) {
  return !name.empty() && name.find_first_of(",\"\r\n") == std::string::npos &&
         name == Trim(name);
}

}  // namespace

std::vector<Track2d> ReadTracks2dCsv(const std::filesystem::path& path) {
  static const std::vector<std::string> header = {"frame", "camera", "marker",
                                                  "x",     "y",      "score"};
  std::vector<Track2d> tracks;
  std::vector<int> lines;
  ForEachCsvRow(path, header, [&](const CsvRow& row) {
    Track2d t;
    t.frame = row.Int(0);
    t.camera = row.NonEmpty(1);
    t.marker = row.NonEmpty(2);
    t.pixel = Vec2(row.Finite(3), row.Finite(4));
    t.score = row.Finite(5);
    if (t.score < 0 || t.score > 1) row.Fail("score {} is outside [0, 1]", t.score);
    tracks.push_back(std::move(t));
    lines.push_back(row.line());
  });
  std::vector<size_t> order(tracks.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) {
    return ByFrameCameraMarker(tracks[a], tracks[b]);
  });
  std::vector<Track2d> sorted;
  sorted.reserve(tracks.size());
  for (size_t k = 0; k < order.size(); ++k) {
    const Track2d& t = tracks[order[k]];
    if (k > 0) {
      const Track2d& prev = tracks[order[k - 1]];
      if (!ByFrameCameraMarker(prev, t)) {
        ThrowInputError(path, lines[order[k]],
                        "marker '{}' repeated in frame {} of camera {} "
                        "(first on line {})",
                        t.marker, t.frame, t.camera, lines[order[k - 1]]);
      }
    }
    sorted.push_back(t);
  }
  return sorted;
}

void WriteTracks2dCsv(const std::filesystem::path& path,
                      std::vector<Track2d> tracks) {
  for (const Track2d& t : tracks) {
    if (!WritableName(t.camera) || !WritableName(t.marker)) {
      ThrowInputError(path, 0,
                      "camera '{}' / marker '{}' cannot be written to CSV "
                      "(empty, a comma, quote, line break or surrounding "
                      "blanks)",
                      t.camera, t.marker);
    }
    if (!t.pixel.allFinite() || !std::isfinite(t.score)) {
      ThrowInputError(path, 0, "cannot write marker {} in frame {}: not finite",
                      t.marker, t.frame);
    }
  }
  std::sort(tracks.begin(), tracks.end(), ByFrameCameraMarker);
  WriteFileAtomic(path, [&](std::ostream& out) {
    out << "frame,camera,marker,x,y,score\n";
    for (const Track2d& t : tracks) {
      out << fmt::format("{},{},{},{:.6f},{:.6f},{:.4f}\n", t.frame, t.camera,
                         t.marker, t.pixel.x(), t.pixel.y(), t.score);
    }
  });
}

std::vector<Dot2dTruth> ReadDots2dCsv(const std::filesystem::path& path) {
  std::vector<std::string> header = {"frame", "camera", "marker", "x",   "y",
                                     "visible", "disc", "cx",   "cy",  "seen",
                                     "cos",   "whole",  "wcx",  "wcy"};
  const std::string text = ReadFile(path);
  // `seen`, then `cos,whole,wcx,wcy` came later: a file whose first
  // non-blank line ends at `cy` or `seen` is read without the later ones.
  bool first = true;
  ForEachLine(text, [&](int number, std::string_view line) {
    if (!first || Trim(line).empty()) return;
    first = false;
    const std::vector<std::string> fields = SplitCsvRecord(line, path, number);
    if (fields.empty() || fields.back() == "cy") {
      header.resize(9);
    } else if (fields.back() == "seen") {
      header.resize(10);
    }
  });
  std::vector<Dot2dTruth> dots;
  ForEachCsvRowInText(text, path, header, [&](const CsvRow& row) {
    Dot2dTruth d;
    d.frame = row.Int(0);
    d.camera = row.NonEmpty(1);
    d.marker = row.NonEmpty(2);
    d.pixel = Vec2(row.Finite(3), row.Finite(4));
    const int visible = row.Int(5);
    if (visible != 0 && visible != 1) row.Fail("visible must be 0 or 1");
    d.visible = visible == 1;
    const std::string& disc = row.Text(6);
    if (disc == "hidden") {
      d.disc = DotDiscState::kHidden;
    } else if (disc == "partial") {
      d.disc = DotDiscState::kPartial;
    } else if (disc == "full") {
      d.disc = DotDiscState::kFull;
    } else {
      row.Fail("disc '{}' is not hidden, partial or full", disc);
    }
    if (!row.Empty(7) || !row.Empty(8)) {
      d.has_centroid = true;
      d.centroid = Vec2(row.Finite(7), row.Finite(8));
    }
    if (row.size() > 9) {
      d.seen = row.Finite(9);
      if (d.seen < 0 || d.seen > 1) row.Fail("seen {} is outside [0, 1]", d.seen);
    }
    if (row.size() > 10) {
      d.has_cos = true;
      d.view_cos = row.Finite(10);
      if (std::abs(d.view_cos) > 1) row.Fail("cos {} is outside [-1, 1]", d.view_cos);
      d.whole = row.Int(11);
      if (d.whole != 0 && d.whole != 1) row.Fail("whole must be 0 or 1");
      if (!row.Empty(12) || !row.Empty(13)) {
        d.has_whole_centroid = true;
        d.whole_centroid = Vec2(row.Finite(12), row.Finite(13));
      }
    }
    dots.push_back(std::move(d));
  });
  return dots;
}

}  // namespace hmc
