#include "tracking/track_fixes.h"

#include <algorithm>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "core/error.h"
#include "core/text.h"

namespace hmc {

const char* TrackFixActionName(TrackFixAction action) {
  switch (action) {
    case TrackFixAction::kRename: return "rename";
    case TrackFixAction::kUnname: return "unname";
    case TrackFixAction::kAbsent: return "absent";
    case TrackFixAction::kMove: return "move";
  }
  return "";
}

std::vector<TrackFix> ReadTrackFixesCsv(const std::filesystem::path& path,
                                        const std::vector<std::string>& cameras,
                                        const std::vector<std::string>& markers) {
  std::vector<TrackFix> fixes;
  auto known = [](const std::vector<std::string>& list, const std::string& name) {
    return list.empty() || std::find(list.begin(), list.end(), name) != list.end();
  };
  ForEachCsvRow(path, {"frame", "camera", "marker", "action", "x", "y", "to"}, [&](const CsvRow& row) {
    TrackFix fix;
    fix.line = row.line();
    fix.frame = row.Int(0);
    if (fix.frame < 1) row.Fail("frame {} must be >= 1", fix.frame);
    fix.camera = row.NonEmpty(1);
    if (!known(cameras, fix.camera)) row.Fail("unknown camera '{}' ({})", fix.camera, fmt::join(cameras, ", "));
    fix.marker = row.Text(2);
    const std::string action = row.Text(3);
    if (action == "rename") fix.action = TrackFixAction::kRename;
    else if (action == "unname") fix.action = TrackFixAction::kUnname;
    else if (action == "absent") fix.action = TrackFixAction::kAbsent;
    else if (action == "move") fix.action = TrackFixAction::kMove;
    else row.Fail("action '{}' is not rename, unname, absent or move", action);
    if (row.Empty(4) != row.Empty(5)) row.Fail("x and y go together: give both or neither");
    fix.has_pixel = !row.Empty(4);
    if (fix.has_pixel) fix.pixel = Vec2(row.Finite(4), row.Finite(5));
    fix.to = row.Text(6);
    if (fix.action == TrackFixAction::kRename && fix.to.empty()) row.Fail("rename needs the new name in `to`");
    if (fix.action != TrackFixAction::kRename && !fix.to.empty()) row.Fail("`to` is for rename only");
    if (fix.action == TrackFixAction::kRename && fix.marker.empty() && !fix.has_pixel) {
      row.Fail("rename needs the dot: its current marker, or x and y");
    }
    if (fix.action == TrackFixAction::kUnname && fix.marker.empty() && !fix.has_pixel) {
      row.Fail("unname needs the dot: its marker, or x and y");
    }
    if ((fix.action == TrackFixAction::kAbsent || fix.action == TrackFixAction::kMove) && fix.marker.empty()) {
      row.Fail("{} needs the marker", action);
    }
    if (fix.action == TrackFixAction::kMove && !fix.has_pixel) row.Fail("move needs x and y");
    for (const std::string* name : {&fix.marker, &fix.to}) {
      if (!name->empty() && !known(markers, *name)) {
        const std::string near = NearestWord(*name, markers, 3);
        row.Fail("unknown marker '{}'{}", *name, near.empty() ? "" : fmt::format(" (did you mean '{}'?)", near));
      }
    }
    fixes.push_back(fix);
  });
  std::stable_sort(fixes.begin(), fixes.end(), [](const TrackFix& a, const TrackFix& b) { return a.frame < b.frame; });
  return fixes;
}

std::string TrackFixesCsvText(const std::vector<TrackFix>& fixes) {
  std::string text = "frame,camera,marker,action,x,y,to\n";
  for (const TrackFix& f : fixes) {
    text += fmt::format("{},{},{},{},{},{},{}\n", f.frame, f.camera, f.marker, TrackFixActionName(f.action),
                        f.has_pixel ? fmt::format("{:.3f}", f.pixel.x()) : "",
                        f.has_pixel ? fmt::format("{:.3f}", f.pixel.y()) : "", f.to);
  }
  return text;
}

}  // namespace hmc
