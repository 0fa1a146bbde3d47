#include "synth/marker_layout.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "core/error.h"
#include "synth/synth_random.h"

namespace hmc {
namespace {

struct Planned {
  std::string name;
  Vec2 st;
  std::vector<std::string> tags;
};

std::string Numbered(const std::string& prefix, int index) {
  return fmt::format("{}_{:02d}", prefix, index);
}

std::vector<Planned> PlanMarkers(const FaceProportions& p) {
  std::vector<Planned> plan;
  auto add = [&](std::string name, double s, double t,
                 std::vector<std::string> tags) {
    plan.push_back({std::move(name), Vec2(s, t), std::move(tags)});
  };
  const double es = p.eye_s, et = p.eye_t, bt = p.brow_t, mt = p.mouth_t,
               mh = p.mouth_half_width, nt = p.nose_tip_t, ct = p.chin_t;

  // Forehead: four rows; the two top rows barely move (stable).
  int n = 0;
  for (double s : {-40.0, -20.0, 0.0, 20.0, 40.0}) {
    add(Numbered("forehead", ++n), s, bt + 54, {"forehead", "stable"});
  }
  for (double t : {bt + 44, bt + 31, bt + 18}) {
    for (double s : {-54.0, -36.0, -18.0, 0.0, 18.0, 36.0, 54.0}) {
      std::vector<std::string> tags = {"forehead"};
      if (t == bt + 44) tags.push_back("stable");
      add(Numbered("forehead", ++n), s, t, tags);
    }
  }
  const std::pair<double, std::string> sides[] = {{1.0, "l"}, {-1.0, "r"}};
  for (const auto& [sd, side] : sides) {
    n = 0;
    for (double s : {10.0, 20.0, 30.0, 40.0, 50.0}) {
      const double arch = 3.0 - 0.002 * (s - 28) * (s - 28);
      add(Numbered("brow_" + side, ++n), sd * s, bt + arch, {"brow"});
    }
    add(Numbered("temple_" + side, 1), sd * 68, 40, {"forehead", "stable"});
    add(Numbered("temple_" + side, 2), sd * 70, 22, {"forehead", "stable"});
  }
  // Nose: bridge (stable), tip, wings, sides.
  n = 0;
  for (double t : {et + 6, et - 2, et - 10}) {
    add(Numbered("nose_bridge", ++n), 0, t, {"nose", "stable"});
  }
  add("nose_01", 0, nt, {"nose"});
  add("nose_02", 15, nt - 4, {"nose"});
  add("nose_03", -15, nt - 4, {"nose"});
  add("nose_04", 11, et - 12, {"nose"});
  add("nose_05", -11, et - 12, {"nose"});
  // Eyes: lids, corners, below the eye.
  for (const auto& [sd, side] : sides) {
    const std::string eye = "eye_" + side;
    const Vec2 ring[] = {{es - 6, et + 4},   {es, et + 5},     {es + 6, et + 4},
                         {es - 6, et - 4.5}, {es, et - 5},     {es + 6, et - 4.5},
                         {es - 14, et},      {es + 14, et},    {es - 8, et - 12},
                         {es, et - 13},      {es + 8, et - 12}};
    n = 0;
    for (const Vec2& q : ring) add(Numbered(eye, ++n), sd * q.x(), q.y(), {eye});
  }
  // Cheeks: a 3 x 5 grid per side; nasolabial line.
  for (const auto& [sd, side] : sides) {
    const std::string cheek = "cheek_" + side;
    n = 0;
    for (double t : {et - 24, nt - 8, mt + 6, mt - 8, mt - 22}) {
      for (double s : {40.0, 52.0, 64.0}) {
        add(Numbered(cheek, ++n), sd * s, t, {cheek});
      }
    }
    n = 0;
    for (double f : {0.15, 0.4, 0.65, 0.9}) {
      const double s = 17 + f * (mh + 6 - 17) + 2.0;
      const double t = (nt - 6) + f * ((mt - 8) - (nt - 6));
      add(Numbered("nasolabial_" + side, ++n), sd * s, t, {cheek, "mouth"});
    }
  }
  // Mouth: both lips (densest), corners, a ring above and below.
  for (int i = 0; i < 9; ++i) {
    const double s = -0.8 * mh + i * (1.6 * mh / 8);
    add(Numbered("mouth_upper", i + 1), s, mt + 3.5, {"mouth"});
    add(Numbered("mouth_lower", i + 1), s, mt - 4.5, {"mouth"});
  }
  add("mouth_corner_l", mh + 1, mt, {"mouth"});
  add("mouth_corner_r", -(mh + 1), mt, {"mouth"});
  n = 0;
  for (double s : {-20.0, -10.0, 0.0, 10.0, 20.0}) {
    add(Numbered("mouth_above", ++n), s, mt + 11, {"mouth"});
  }
  n = 0;
  for (double s : {-20.0, -10.0, 0.0, 10.0, 20.0}) {
    add(Numbered("mouth_below", ++n), s, mt - 12, {"mouth"});
  }
  // Chin and jaw line: they follow the jaw.
  const Vec2 chin[] = {{0, ct}, {10, ct}, {-10, ct}, {12, ct + 10},
                       {-12, ct + 10}, {8, ct - 9}, {-8, ct - 9}};
  n = 0;
  for (const Vec2& q : chin) add(Numbered("chin", ++n), q.x(), q.y(), {"chin", "jaw"});
  for (const auto& [sd, side] : sides) {
    const Vec2 line[] = {{25, ct - 6}, {42, ct + 2}, {58, mt - 22},
                         {72, mt - 12}, {84, mt - 2}};
    n = 0;
    for (const Vec2& q : line) {
      add(Numbered("jaw_" + side, ++n), sd * q.x(), q.y(), {"jaw"});
    }
  }
  return plan;
}

}  // namespace

std::vector<Marker> LayoutMarkers(const FaceMesh& face, uint64_t seed,
                                  double jitter_mm) {
  SynthRandom rng = SynthRandom::Stream(seed, 2);
  std::vector<Marker> markers;
  for (const Planned& planned : PlanMarkers(face.proportions)) {
    Vec2 st = planned.st;
    for (int k = 0; k < 2; ++k) {
      st[k] += jitter_mm * std::clamp(rng.Normal(), -2.0, 2.0);
    }
    // Off the mouth slit: step away from the mouth until on a triangle.
    const double away = st.y() >= face.proportions.mouth_t ? 1.0 : -1.0;
    SurfacePoint point = FaceSurfacePoint(face, st);
    for (int step = 0; point.face < 0 && step < 8; ++step) {
      st.y() += away * 0.5 * face.row_spacing;
      point = FaceSurfacePoint(face, st);
    }
    HMC_CHECK_MSG(point.face >= 0, "marker " + planned.name + " is off the mesh");
    Marker marker;
    marker.name = planned.name;
    marker.point = point;
    marker.tags = planned.tags;
    markers.push_back(std::move(marker));
  }
  return markers;
}

}  // namespace hmc
