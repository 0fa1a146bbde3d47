#include "synth/action_units.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include "core/error.h"

namespace hmc {
namespace {

using Field = std::function<Vec3(const VertexContext&)>;
using Coefficient = std::function<double(const Eigen::VectorXd&)>;

// A region-localised displacement: compact bump at (s, t) with radii
// (rs, rt), displacement `d` (head space, mm) plus `normal` mm along the
// neutral normal at its centre.
struct Blob {
  double s, t, rs, rt;
  Vec3 d;
  double normal = 0.0;
};

// Blobs given for the actor's left side (s > 0), placed on `side` (+1 left,
// -1 right: s and d.x mirror).
Field Blobs(std::vector<Blob> blobs, double side) {
  for (Blob& b : blobs) {
    b.s *= side;
    b.d.x() *= side;
  }
  return [blobs](const VertexContext& c) -> Vec3 {
    Vec3 out = Vec3::Zero();
    for (const Blob& b : blobs) {
      const double w = CompactBump(c.st.x() - b.s, c.st.y() - b.t, b.rs, b.rt);
      if (w > 0) out += w * (b.d + b.normal * c.normal);
    }
    return out;
  };
}

// The blobs on both sides.
Field Mirrored(const std::vector<Blob>& blobs) {
  Field left = Blobs(blobs, 1.0), right = Blobs(blobs, -1.0);
  return [left, right](const VertexContext& c) -> Vec3 { return left(c) + right(c); };
}

Field Sum(Field a, Field b) {
  return [a, b](const VertexContext& c) -> Vec3 { return a(c) + b(c); };
}

// Only where the jaw does not fully carry the tissue, so a fully weighted
// vertex moves rigidly with the jaw.
Field OffJaw(Field f) {
  return [f](const VertexContext& c) -> Vec3 { return (1.0 - c.jaw_weight) * f(c); };
}

// A scalar pattern (mm) applied along the neutral normal.
Field AlongNormal(std::function<double(const Vec2&)> pattern) {
  return [pattern](const VertexContext& c) -> Vec3 { return pattern(c.st) * c.normal; };
}

double Gauss1(double d, double r) { return std::exp(-0.5 * (d / r) * (d / r)); }

double SegmentDistance(double px, double py, double ax, double ay, double bx,
                       double by, double* cross) {
  const double dx = bx - ax, dy = by - ay;
  double f = ((px - ax) * dx + (py - ay) * dy) / (dx * dx + dy * dy);
  f = std::clamp(f, 0.0, 1.0);
  *cross = dx * (py - ay) - dy * (px - ax);
  return std::hypot(px - (ax + f * dx), py - (ay + f * dy));
}

Coefficient Ease(int k) {
  return [k](const Eigen::VectorXd& a) { return a[k] * (1.3 - 0.3 * a[k]); };
}
Coefficient Power(int k, double power) {
  return [k, power](const Eigen::VectorXd& a) { return std::pow(a[k], power); };
}
Coefficient Beyond(int k, double threshold) {
  return [k, threshold](const Eigen::VectorXd& a) {
    return SmoothStep(threshold, 1.0, a[k]);
  };
}
Coefficient Product(int i, int j) {
  return [i, j](const Eigen::VectorXd& a) { return a[i] * a[j]; };
}

// The fine-detail patterns (mm along the normal), parameterised by the face.
class Details {
 public:
  Details(const FaceProportions& p, double scale) : p_(p), scale_(scale) {}

  // Horizontal forehead lines, slightly arched, centred at s = centre.
  Field ForeheadWrinkles(double centre, double half_width, double amp) const {
    const FaceProportions p = p_;
    const double a = amp * scale_;
    return AlongNormal([=](const Vec2& st) {
      const double env =
          CompactBump(st.x() - centre, st.y() - (p.brow_t + 30), half_width, 26);
      if (env == 0) return 0.0;
      const double t_arched = st.y() + 0.0025 * st.x() * st.x();
      return a * env * std::cos(2 * M_PI * t_arched / 9.0 + p.detail_phase);
    });
  }

  // Vertical furrows between the brows.
  Field GlabellaFurrows(double amp) const {
    const FaceProportions p = p_;
    const double a = amp * scale_;
    return AlongNormal([=](const Vec2& st) {
      const double env = CompactBump(st.x(), st.y() - (p.brow_t - 2), 13, 12);
      if (env == 0) return 0.0;
      return -a * env * (0.5 + 0.5 * std::cos(2 * M_PI * st.x() / 7.0));
    });
  }

  // Lines fanning out from the outer eye corner of `side`.
  Field CrowsFeet(double side, double amp) const {
    const FaceProportions p = p_;
    const double a = amp * scale_;
    return AlongNormal([=](const Vec2& st) {
      const double ds = side * st.x() - (p.eye_s + 12), dt = st.y() - p.eye_t;
      const double r = std::hypot(ds, dt);
      const double angle = std::atan2(dt, ds);  // 0: straight out sideways
      const double env = SmoothStep(3, 7, r) * (1 - SmoothStep(14, 24, r)) *
                         Gauss1(angle, 0.6);
      if (env < 1e-6) return 0.0;
      return a * env * std::cos(9.0 * angle + p.detail_phase);
    });
  }

  // Diagonal lines on the sides of the nose bridge ("bunny lines").
  Field BunnyLines(double amp) const {
    const FaceProportions p = p_;
    const double a = amp * scale_;
    return AlongNormal([=](const Vec2& st) {
      const double env = CompactBump(st.x(), st.y() - (p.eye_t - 4), 18, 13);
      if (env == 0) return 0.0;
      return a * env *
             std::cos(2 * M_PI * (st.y() - 0.8 * std::abs(st.x())) / 5.5 +
                      p.detail_phase);
    });
  }

  // Nasolabial fold of `side` (0: both): a crease from the nose wing to past
  // the mouth corner, with the cheek bulging over it on the lateral side.
  Field NasolabialFold(double side, double amp) const {
    const FaceProportions p = p_;
    const double a = amp * scale_;
    return AlongNormal([=](const Vec2& st) {
      if (side != 0 && side * st.x() <= 0) return 0.0;
      double cross = 0;
      const double d = SegmentDistance(
          std::abs(st.x()), st.y(), 17, p.nose_tip_t - 6,
          p.mouth_half_width + 6, p.mouth_t - 8, &cross);
      if (d > 14) return 0.0;
      const double crease = -Gauss1(d, 1.6);
      const double bulge = cross > 0 ? 0.8 * Gauss1(d - 4.5, 3.0) : 0.0;
      return a * (crease + bulge);
    });
  }

  // Pits and bumps on the chin ("orange peel" of the chin raiser).
  Field ChinDimpling(double amp) const {
    const FaceProportions p = p_;
    const double a = amp * scale_;
    return AlongNormal([=](const Vec2& st) {
      const double env = CompactBump(st.x(), st.y() - p.chin_t, 20, 14);
      if (env == 0) return 0.0;
      const double ph = p.detail_phase;
      return a * env *
             (std::cos(2 * M_PI * st.x() / 5.0 + ph) *
                  std::cos(2 * M_PI * st.y() / 4.6 + 0.7 * ph) +
              0.5 * std::cos(2 * M_PI * (st.x() + st.y()) / 3.8 + 1.3 * ph));
    });
  }

  // Vertical lines on and around the lips (pucker, funnel).
  Field LipWrinkles(double amp) const {
    const FaceProportions p = p_;
    const double a = amp * scale_;
    return AlongNormal([=](const Vec2& st) {
      const double env = CompactBump(st.x(), st.y() - p.mouth_t,
                                     p.mouth_half_width + 6, 14);
      if (env == 0) return 0.0;
      return a * env * std::cos(2 * M_PI * st.x() / 5.0 + p.detail_phase);
    });
  }

  // A dimple pit lateral to the mouth corner.
  Field Dimple(double side, double amp) const {
    const FaceProportions p = p_;
    const double a = amp * scale_;
    return AlongNormal([=](const Vec2& st) {
      return -a * CompactBump(st.x() - side * (p.mouth_half_width + 7),
                              st.y() - (p.mouth_t - 3), 5, 5);
    });
  }

  // Marionette line: a crease running down from the mouth corner.
  Field MarionetteLine(double side, double amp) const {
    const FaceProportions p = p_;
    const double a = amp * scale_;
    return AlongNormal([=](const Vec2& st) {
      if (side * st.x() <= 0) return 0.0;
      double cross = 0;
      const double d = SegmentDistance(
          std::abs(st.x()), st.y(), p.mouth_half_width + 2, p.mouth_t - 4,
          p.mouth_half_width + 7, p.mouth_t - 24, &cross);
      return -a * Gauss1(d, 1.8);
    });
  }

  // Fold under the lower lid when the cheek rises.
  Field InfraorbitalFold(double side, double amp) const {
    const FaceProportions p = p_;
    const double a = amp * scale_;
    return AlongNormal([=](const Vec2& st) {
      const double ex = side * st.x() - p.eye_s;
      if (side * st.x() <= 0 || std::abs(ex) >= 18) return 0.0;
      const double m = 1 - (ex / 18) * (ex / 18);
      return -a * m * m * Gauss1(st.y() - (p.eye_t - 9 + 0.01 * ex * ex), 1.5);
    });
  }

  // Cords on the side of the neck (platysma) of the lip stretcher.
  Field NeckCords(double side, double amp) const {
    const double a = amp * scale_;
    return AlongNormal([=](const Vec2& st) {
      const double env = CompactBump(st.x() - side * 35, st.y() + 112, 22, 20);
      if (env == 0) return 0.0;
      return a * env * std::max(0.0, std::cos(2 * M_PI * st.x() / 11.0));
    });
  }

  // A band along the normal at height t0 relative to the mouth (lip
  // thinning < 0, bulges > 0).
  Field MouthBand(double t0, double half_width, double half_height,
                  double amp) const {
    const FaceProportions p = p_;
    const double a = amp * scale_;
    return AlongNormal([=](const Vec2& st) {
      return a * CompactBump(st.x(), st.y() - (p.mouth_t + t0), half_width,
                             half_height);
    });
  }

 private:
  FaceProportions p_;
  double scale_;
};

// A broad region of the broad rig: weight 1 on s in [s_lo, s_hi] and t in
// [t_lo, t_hi], falling smoothly to 0 over `soft` mm outside; inside, the
// displacement goes linearly from `low` (at t_lo) to `high` (at t_hi), plus
// `normal` mm along the neutral normal. Given for the actor's left side.
struct Region {
  double s_lo, s_hi, t_lo, t_hi, soft;
  Vec3 low, high;
  double normal = 0.0;
};

double Window(double x, double lo, double hi, double soft) {
  return SmoothStep(lo - soft, lo, x) * (1.0 - SmoothStep(hi, hi + soft, x));
}

Vec3 RegionAt(const Region& r, const VertexContext& c, double s, double x_sign) {
  const double w = Window(s, r.s_lo, r.s_hi, r.soft) * Window(c.st.y(), r.t_lo, r.t_hi, r.soft);
  if (w == 0) return Vec3::Zero();
  const double f = std::clamp((c.st.y() - r.t_lo) / (r.t_hi - r.t_lo), 0.0, 1.0);
  Vec3 d = (1 - f) * r.low + f * r.high;
  d.x() *= x_sign;
  return w * (d + r.normal * c.normal);
}

// The regions placed on `side` (+1 left, -1 right: s and x mirror).
Field Regions(std::vector<Region> regions, double side) {
  return [regions, side](const VertexContext& c) -> Vec3 {
    Vec3 out = Vec3::Zero();
    for (const Region& r : regions) out += RegionAt(r, c, side * c.st.x(), side);
    return out;
  };
}

// Regions across the midline, symmetric: the window is on s in [-s_hi, s_hi]
// (s_lo unused), and a positive x displacement points away from the midline
// on either side (fading through 0 within 15 mm of it).
Field Symmetric(std::vector<Region> regions) {
  for (Region& r : regions) r.s_lo = -r.s_hi;
  return [regions](const VertexContext& c) -> Vec3 {
    const double x_sign = std::clamp(c.st.x() / 15.0, -1.0, 1.0);
    Vec3 out = Vec3::Zero();
    for (const Region& r : regions) out += RegionAt(r, c, c.st.x(), x_sign);
    return out;
  };
}

class Builder {
 public:
  explicit Builder(UnitCatalog* catalog) : catalog_(catalog) {}

  int Unit(const std::string& name, std::vector<std::string> tags,
           bool drives_jaw = false) {
    catalog_->units.push_back({name, std::move(tags), drives_jaw});
    return static_cast<int>(catalog_->units.size()) - 1;
  }
  void Term(const std::string& label, Coefficient coefficient, Field field) {
    catalog_->terms.push_back({label, std::move(coefficient), std::move(field)});
  }

 private:
  UnitCatalog* catalog_;
};

}  // namespace

int UnitCatalog::Find(const std::string& name) const {
  for (size_t k = 0; k < units.size(); ++k) {
    if (units[k].name == name) return static_cast<int>(k);
  }
  return -1;
}

UnitCatalog BuildUnitCatalog(const FaceProportions& p, double detail_scale) {
  UnitCatalog catalog;
  Builder b(&catalog);
  const Details detail(p, detail_scale);
  const double es = p.eye_s, et = p.eye_t, bt = p.brow_t, mt = p.mouth_t,
               mh = p.mouth_half_width, nt = p.nose_tip_t, ct = p.chin_t;
  const std::pair<double, std::string> sides[] = {{1.0, "L"}, {-1.0, "R"}};
  auto side_tag = [](const std::string& region, const std::string& side) {
    return region + (side == "L" ? "_l" : "_r");
  };
  int au01[2], au02[2], au06[2], au12[2], au45[2];

  // A brow raiser on each side (AU01 inner, AU02 outer): the brow lifts
  // (`lift`, given for the left side) and the forehead wrinkles over
  // ForeheadWrinkles(s, width, amp) as `wrinkling` of the unit grows.
  auto brow_raiser = [&](const std::string& au, const std::string& unit,
                         const std::vector<Blob>& lift,
                         const std::function<Coefficient(int)>& wrinkling,
                         double wrinkle_s, double wrinkle_width,
                         double wrinkle_amp, int out[2]) {
    for (int i = 0; i < 2; ++i) {
      const auto& [sd, name] = sides[i];
      out[i] = b.Unit(au + "_" + unit + "_" + name, {"brow", "forehead"});
      b.Term(name + " " + au, Ease(out[i]), Blobs(lift, sd));
      b.Term(name + " " + au + " wrinkles", wrinkling(out[i]),
             detail.ForeheadWrinkles(sd * wrinkle_s, wrinkle_width, wrinkle_amp));
    }
  };
  brow_raiser("AU01", "inner_brow_raiser",
              {{14, bt + 2, 20, 22, Vec3(0, 9, 1)},
               {14, bt + 22, 22, 26, Vec3(0, 4, 0)}},
              [](int k) { return Power(k, 2); }, 12, 34, 0.9, au01);
  brow_raiser("AU02", "outer_brow_raiser",
              {{42, bt + 1, 22, 20, Vec3(1, 8, 0)},
               {40, bt + 20, 24, 24, Vec3(0, 3.5, 0)}},
              [](int k) { return Beyond(k, 0.3); }, 40, 30, 0.8, au02);
  const int au04 = b.Unit("AU04_brow_lowerer", {"brow", "forehead"});
  b.Term("AU04", Ease(au04),
         Mirrored({{18, bt, 20, 16, Vec3(-3.5, -6, 1.5)},
                   {10, bt - 8, 10, 10, Vec3(-2, -3, 1)}}));
  b.Term("AU04 furrows", Power(au04, 2), detail.GlabellaFurrows(1.1));

  const int au05 = b.Unit("AU05_upper_lid_raiser", {"eye_l", "eye_r"});
  b.Term("AU05", Ease(au05),
         Mirrored({{es, et + 5, 15, 8, Vec3(0, 3, 0.5)},
                   {es, bt, 20, 10, Vec3(0, 1.5, 0)}}));
  b.Term("AU05 crease", Power(au05, 2),
         Mirrored({{es, et + 8, 14, 2.5, Vec3::Zero(), -0.8 * detail_scale}}));

  for (int i = 0; i < 2; ++i) {
    const auto& [sd, name] = sides[i];
    au06[i] = b.Unit("AU06_cheek_raiser_" + name,
                     {side_tag("cheek", name), side_tag("eye", name)});
    b.Term(name + " AU06", Ease(au06[i]),
           Blobs({{es + 5, et - 14, 26, 18, Vec3(0.5, 5, 3)},
                  {es, et - 4, 15, 5, Vec3(0, 2, 1)}}, sd));
    b.Term(name + " AU06 crow's feet", Beyond(au06[i], 0.4),
           detail.CrowsFeet(sd, 0.45));
    b.Term(name + " AU06 lid fold", Power(au06[i], 2),
           detail.InfraorbitalFold(sd, 1.0));
  }
  const int au07 = b.Unit("AU07_lid_tightener", {"eye_l", "eye_r"});
  b.Term("AU07", Ease(au07),
         Mirrored({{es, et - 2.5, 14, 4, Vec3(0, 2.5, 0)},
                   {es, et + 3, 14, 4, Vec3(0, -1.5, 0)}}));
  b.Term("AU07 lid bulge", Power(au07, 2),
         Mirrored({{es, et - 5, 14, 3, Vec3::Zero(), 0.8 * detail_scale}}));

  for (int i = 0; i < 2; ++i) {
    const auto& [sd, name] = sides[i];
    au45[i] = b.Unit("AU45_blink_" + name, {side_tag("eye", name)});
    // The lids close faster towards the end of a blink.
    const int k = au45[i];
    b.Term(name + " AU45", Power(k, 1.6),
           Blobs({{es, et + 3, 15, 6.5, Vec3(0, -4.5, 1.0)},
                  {es, et - 3, 13, 4, Vec3(0, 1, 0.3)}}, sd));
    b.Term(name + " AU45 lid crease", Power(k, 2),
           Blobs({{es, et + 8, 14, 2.5, Vec3::Zero(), 0.8 * detail_scale}}, sd));
    b.Term(name + " AU45 crow's feet", Power(k, 3), detail.CrowsFeet(sd, 0.3));
  }

  const int au09 = b.Unit("AU09_nose_wrinkler", {"nose", "brow"});
  b.Term("AU09", Ease(au09),
         Mirrored({{9, et - 8, 9, 12, Vec3(0, 3, 1)},
                   {15, nt - 6, 8, 8, Vec3(0.5, 3, 1)},
                   {16, bt - 3, 12, 8, Vec3(-1, -3, 0)},
                   {8, mt + 8, 12, 8, Vec3(0, 1.5, 0.5)}}));
  b.Term("AU09 bunny lines", Power(au09, 2), detail.BunnyLines(0.7));

  const int au10 = b.Unit("AU10_upper_lip_raiser", {"mouth", "nose"});
  b.Term("AU10", Ease(au10),
         Mirrored({{10, mt + 5, 16, 8, Vec3(0, 4, 1.5)},
                   {22, nt - 8, 10, 12, Vec3(0.5, 3, 1)}}));
  b.Term("AU10 nasolabial", Power(au10, 2), detail.NasolabialFold(0, 1.2));

  const int au11 =
      b.Unit("AU11_nasolabial_deepener", {"mouth", "cheek_l", "cheek_r"});
  b.Term("AU11", Ease(au11), Mirrored({{28, nt - 10, 12, 14, Vec3(1, 3, 2)}}));
  b.Term("AU11 fold", Power(au11, 1.5), detail.NasolabialFold(0, 2.0));

  for (int i = 0; i < 2; ++i) {
    const auto& [sd, name] = sides[i];
    au12[i] = b.Unit("AU12_lip_corner_puller_" + name,
                     {"mouth", side_tag("cheek", name)});
    b.Term(name + " AU12", Ease(au12[i]),
           Blobs({{mh, mt, 18, 14, Vec3(8, 6, -2.5)},
                  {mh + 14, nt - 5, 22, 18, Vec3(2, 4, 3)},
                  {mh - 8, mt, 12, 8, Vec3(3, 1, 0), -1.0}}, sd));
    b.Term(name + " AU12 nasolabial", Beyond(au12[i], 0.25),
           detail.NasolabialFold(sd, 2.2));
  }

  const int au14 = b.Unit("AU14_dimpler", {"mouth"});
  b.Term("AU14", Ease(au14), Mirrored({{mh, mt - 1, 8, 8, Vec3(1.5, 0, -3)}}));
  b.Term("AU14 dimples", Power(au14, 2),
         Sum(detail.Dimple(1, 2.5), detail.Dimple(-1, 2.5)));

  for (int i = 0; i < 2; ++i) {
    const auto& [sd, name] = sides[i];
    const int k = b.Unit("AU15_lip_corner_depressor_" + name, {"mouth", "chin"});
    b.Term(name + " AU15", Ease(k),
           Blobs({{mh, mt - 2, 16, 14, Vec3(1, -6, -1)},
                  {mh + 4, mt - 16, 14, 14, Vec3(0, -2, 0)}}, sd));
    b.Term(name + " AU15 marionette", Power(k, 2),
           detail.MarionetteLine(sd, 1.6));
  }

  const int au16 = b.Unit("AU16_lower_lip_depressor", {"mouth", "chin"});
  b.Term("AU16", Ease(au16), Mirrored({{9, mt - 5, 14, 8, Vec3(1, -5, 2)}}));
  b.Term("AU16 eversion", Power(au16, 2),
         detail.MouthBand(-5, mh, 4, 1.0));

  const int au17 = b.Unit("AU17_chin_raiser", {"chin", "mouth"});
  b.Term("AU17", Ease(au17),
         Blobs({{0, ct + 4, 24, 18, Vec3(0, 5, 3)},
                {0, mt - 6, 24, 8, Vec3(0, 2.5, 3)}}, 1.0));
  b.Term("AU17 dimpling", Beyond(au17, 0.3), detail.ChinDimpling(0.6));
  b.Term("AU17 sulcus", Power(au17, 2), detail.MouthBand(-16, 20, 4, -1.5));

  const int au18 = b.Unit("AU18_lip_puckerer", {"mouth"});
  b.Term("AU18", Ease(au18), Mirrored({{12, mt, 20, 14, Vec3(-5, 0, 6)}}));
  b.Term("AU18 lip lines", Power(au18, 2), detail.LipWrinkles(0.7));

  for (int i = 0; i < 2; ++i) {
    const auto& [sd, name] = sides[i];
    const int k = b.Unit("AU20_lip_stretcher_" + name,
                         {"mouth", side_tag("cheek", name)});
    b.Term(name + " AU20", Ease(k),
           Blobs({{mh, mt, 18, 14, Vec3(7, -1, -2.5)},
                  {mh + 10, mt - 20, 22, 20, Vec3(2, -1, -1)}}, sd));
    b.Term(name + " AU20 neck", Beyond(k, 0.4), detail.NeckCords(sd, 0.8));
    b.Term(name + " AU20 thinning", Power(k, 2),
           Blobs({{mh - 8, mt, 14, 7, Vec3::Zero(), -1.0}}, sd));
  }

  const int au22 = b.Unit("AU22_lip_funneler", {"mouth"});
  b.Term("AU22", Ease(au22),
         Sum(Blobs({{0, mt + 5, 26, 8, Vec3(0, 2, 6)},
                    {0, mt - 6, 24, 8, Vec3(0, -2, 6)}}, 1.0),
             Mirrored({{mh, mt, 10, 10, Vec3(-4, 0, 2)}})));
  b.Term("AU22 lip lines", Power(au22, 2), detail.LipWrinkles(0.5));

  const int au23 = b.Unit("AU23_lip_tightener", {"mouth"});
  b.Term("AU23", Ease(au23),
         Blobs({{0, mt + 4, 26, 6, Vec3(0, -1, -1.5)},
                {0, mt - 5, 24, 6, Vec3(0, 1, -1.5)}}, 1.0));
  b.Term("AU23 thinning", Power(au23, 2),
         Sum(detail.MouthBand(4, mh, 3.5, -1.5), detail.MouthBand(-5, mh, 3.5, -1.5)));

  const int au24 = b.Unit("AU24_lip_pressor", {"mouth", "chin"});
  b.Term("AU24", Ease(au24),
         Blobs({{0, mt + 4, 26, 7, Vec3(0, -1.5, -1)},
                {0, mt - 5, 24, 7, Vec3(0, 2, -1)}}, 1.0));
  // Pressed lips push tissue out above and below them (volume).
  b.Term("AU24 bulges", Power(au24, 2),
         Sum(detail.MouthBand(11, 22, 5, 1.5), detail.MouthBand(-13, 20, 5, 1.5)));

  const int au34 = b.Unit("AU34_cheek_puff", {"cheek_l", "cheek_r", "mouth"});
  // Inflation: slow at first, then the cheeks balloon.
  b.Term("AU34", Power(au34, 1.5),
         Sum(Mirrored({{40, mt + 2, 30, 26, Vec3::Zero(), 9.0}}),
             Blobs({{0, mt, 20, 10, Vec3(0, 0, 2)}}, 1.0)));
  b.Term("AU34 fold smoothing", Power(au34, 2), detail.NasolabialFold(0, -0.8));

  const int au26 = b.Unit("AU26_jaw_drop", {"jaw", "chin", "mouth"}, true);
  b.Term("AU26 soft tissue", Power(au26, 2),
         OffJaw(Mirrored({{45, mt - 5, 30, 28, Vec3::Zero(), -2.5},
                          {mh, mt, 10, 10, Vec3(0, -1, -1)}})));
  const int au27 = b.Unit("AU27_mouth_stretch", {"jaw", "mouth"}, true);
  b.Term("AU27 corners", Ease(au27),
         OffJaw(Mirrored({{mh, mt, 14, 12, Vec3(2.5, -3, -1)}})));
  b.Term("AU27 thinning", Power(au27, 2),
         Sum(detail.MouthBand(4, mh, 3.5, -1.0), detail.MouthBand(-5, mh, 3.5, -1.0)));
  const int au29 = b.Unit("AU29_jaw_thrust", {"jaw", "chin"}, true);
  b.Term("AU29 soft tissue", Ease(au29),
         OffJaw(Mirrored({{mh + 5, mt - 5, 16, 16, Vec3(0, 0, 1.5)}})));
  int au30[2];
  for (int i = 0; i < 2; ++i) {
    const auto& [sd, name] = sides[i];
    au30[i] = b.Unit("AU30_jaw_sideways_" + name, {"jaw", "chin"}, true);
    b.Term(name + " AU30 soft tissue", Ease(au30[i]),
           OffJaw(Sum(Blobs({{40, mt - 10, 30, 30, Vec3(1.5, 0, 0)}}, sd),
                      Blobs({{-40, mt - 10, 30, 30, Vec3(1.5, 0, 0)}}, sd))));
  }

  // Interactions: combinations are not the sum of their parts.
  for (int i = 0; i < 2; ++i) {
    const auto& [sd, name] = sides[i];
    b.Term(name + " smile x cheek raiser", Product(au12[i], au06[i]),
           Sum(detail.CrowsFeet(sd, 0.9),
               Blobs({{es + 5, et - 12, 18, 12, Vec3(0, 2.5, 2)}}, sd)));
    b.Term(name + " inner x outer brow", Product(au01[i], au02[i]),
           detail.ForeheadWrinkles(sd * 28, 30, 0.6));
    b.Term(name + " blink x cheek raiser", Product(au45[i], au06[i]),
           detail.CrowsFeet(sd, 0.5));
    b.Term(name + " smile x jaw drop", Product(au12[i], au26),
           Sum(OffJaw(Blobs({{mh, mt, 14, 12, Vec3(1, 0, -2)}}, sd)),
               detail.NasolabialFold(sd, 1.0)));
  }
  b.Term("smile L x smile R", Product(au12[0], au12[1]),
         Mirrored({{mh + 14, nt - 5, 20, 16, Vec3(0, 1.5, 1.5)},
                   {es, et - 4, 14, 5, Vec3(0, 1, 0)}}));
  b.Term("jaw drop x funneler", Product(au26, au22),
         Blobs({{0, mt, 24, 14, Vec3(0, 0, 3.5)}}, 1.0));
  b.Term("lip pressor x chin raiser", Product(au24, au17),
         Sum(Blobs({{0, ct + 6, 18, 10, Vec3::Zero(), 2.5}}, 1.0),
             detail.ChinDimpling(0.5)));
  b.Term("pucker x funneler", Product(au18, au22),
         Blobs({{0, mt, 22, 12, Vec3(0, 0, -3.5)}}, 1.0));
  b.Term("nose wrinkler x upper lip raiser", Product(au09, au10),
         detail.NasolabialFold(0, 1.5));
  const int inner_l = au01[0], inner_r = au01[1];
  b.Term("brow lowerer x inner brow raiser",
         [au04, inner_l, inner_r](const Eigen::VectorXd& a) {
           return a[au04] * 0.5 * (a[inner_l] + a[inner_r]);
         },
         Sum(detail.GlabellaFurrows(0.6),
             detail.ForeheadWrinkles(0, 20, 0.6)));

  const int lat_l = au30[0], lat_r = au30[1];
  catalog.jaw_pose = [au26, au27, au29, lat_l, lat_r](const Eigen::VectorXd& a) {
    JawPose pose;
    // Opening saturates softly (tanh) when drop and stretch combine.
    pose.open_deg = 40.0 * std::tanh((30.0 * a[au26] + 22.0 * a[au27]) / 40.0);
    pose.lateral_deg = 8.0 * (a[lat_l] - a[lat_r]);
    pose.protrude_mm = 5.0 * a[au29] - 1.5 * a[au29] * a[au26];
    return pose;
  };
  return catalog;
}

void AddBroadRegions(const FaceProportions& p, UnitCatalog* catalog) {
  const double et = p.eye_t, bt = p.brow_t, mt = p.mouth_t, nt = p.nose_tip_t,
               ct = p.chin_t;
  const double top = kTMax;  // the hairline: the mesh's top row
  catalog->units.push_back({"mouth_left", {"mouth", "chin", "jaw", "cheek_l", "cheek_r"}});
  catalog->units.push_back({"mouth_right", {"mouth", "chin", "jaw", "cheek_l", "cheek_r"}});
  catalog->broad.assign(catalog->units.size(), nullptr);
  auto set = [&](const std::string& name, Field field, std::vector<std::string> tags) {
    const int k = catalog->Find(name);
    HMC_CHECK_MSG(k >= 0, "broad rig: unknown unit " + name);
    catalog->broad[k] = std::move(field);
    std::vector<std::string>& own = catalog->units[k].tags;
    for (std::string& tag : tags) {
      if (std::find(own.begin(), own.end(), tag) == own.end()) own.push_back(std::move(tag));
    }
  };
  // Mirrored pairs: regions given for the left side, on both.
  auto both = [](const std::vector<Region>& regions) {
    return Sum(Regions(regions, 1.0), Regions(regions, -1.0));
  };
  // The temple, pulled towards the eye by the orbicularis (squint, blink,
  // smile) or down by the jaw.
  auto temple = [&](Vec3 d) { return Region{55, 95, et - 6, bt + 14, 12, d, d}; };
  const std::pair<double, std::string> sides[] = {{1.0, "L"}, {-1.0, "R"}};
  for (const auto& [sd, name] : sides) {
    const std::string cheek = sd > 0 ? "cheek_l" : "cheek_r";
    const std::string eye = sd > 0 ? "eye_l" : "eye_r";
    const std::string other_cheek = sd > 0 ? "cheek_r" : "cheek_l";
    // Brow raisers: the whole forehead up to the hairline, most at the brow.
    set("AU01_inner_brow_raiser_" + name,
        Regions({{-15, 40, bt - 8, top, 15, Vec3(0, 6, 0.5), Vec3(0, 2, 0)}}, sd),
        {"forehead", "brow", "nose"});
    set("AU02_outer_brow_raiser_" + name,
        Regions({{20, 75, bt - 8, top, 15, Vec3(0.5, 5, 0), Vec3(0, 1.5, 0)}}, sd),
        {"forehead", "brow", eye});
    // Cheek raiser: the cheek from the mouth up to the lower lid, the temple in.
    set("AU06_cheek_raiser_" + name,
        Regions({{15, 80, mt, et - 4, 12, Vec3(0.5, 2, 1), Vec3(0, 3.5, 1)},
                 temple(Vec3(-1.5, -0.5, 0))}, sd),
        {cheek, eye, "forehead", "mouth"});
    set("AU45_blink_" + name,
        Regions({{15, 60, et - 12, bt + 10, 10, Vec3(0, -0.8, 0.2), Vec3(0, -0.8, 0.2)},
                 temple(Vec3(-0.6, 0, 0))}, sd),
        {eye, "brow", cheek, "forehead"});
    // Smile: the lower face drawn sideways, the cheek lifted up to the lower
    // lid, the crow's-feet region and temple pushed.
    set("AU12_lip_corner_puller_" + name,
        Regions({{0, 90, ct + 10, et - 4, 15, Vec3(2.5, 1.5, -0.5), Vec3(0.5, 3, 1.5)},
                 {-30, 30, ct - 20, mt, 15, Vec3(1, 0.5, 0), Vec3(1, 0.5, 0)},
                 temple(Vec3(-0.8, 0.8, 0))}, sd),
        {cheek, eye, "chin", "jaw", "forehead", "nose"});
    set("AU15_lip_corner_depressor_" + name,
        Regions({{0, 80, ct - 25, mt + 5, 15, Vec3(0, -1, 0), Vec3(0.5, -3, -0.5)},
                 {30, 80, mt, nt, 12, Vec3(0, -1, 0), Vec3(0, -1, 0)}}, sd),
        {cheek, "jaw"});
    set("AU20_lip_stretcher_" + name,
        Regions({{0, 95, ct - 40, nt, 15, Vec3(2, -0.8, -0.5), Vec3(2, -0.8, -0.5)}}, sd),
        {"chin", "jaw", other_cheek});
    // Jaw sideways and mouth left/right: the whole lower face.
    set("AU30_jaw_sideways_" + name,
        Regions({{-110, 110, ct - 40, nt + 10, 15, Vec3(3.5, 0, 0), Vec3(1, 0, 0)}}, sd),
        {"mouth", "cheek_l", "cheek_r"});
    set(sd > 0 ? "mouth_left" : "mouth_right",
        Regions({{-110, 110, ct - 40, nt + 10, 15, Vec3(1.5, 0, 0), Vec3(0.8, 0, 0)},
                 {-45, 45, mt - 15, mt + 15, 12, Vec3(4, 0.5, -0.5), Vec3(4, 0.5, -0.5)}}, sd),
        {});
  }
  set("AU04_brow_lowerer",
      Symmetric({{0, 45, bt - 15, top, 15, Vec3(-2, -4, 0.5), Vec3(0, -1, 0)},
                 {0, 10, et - 15, bt - 15, 8, Vec3(0, -1.5, 0.5), Vec3(0, -1.5, 0.5)}}),
      {"nose", "eye_l", "eye_r"});
  set("AU05_upper_lid_raiser",
      both({{10, 60, et, top, 12, Vec3(0, 1.5, 0), Vec3(0, 0.5, 0)}}),
      {"brow", "forehead"});
  set("AU07_lid_tightener",
      both({{10, 60, et - 15, et + 12, 10, Vec3(0, 1, 0.3), Vec3(0, -0.5, 0)},
            {10, 60, bt - 5, bt + 30, 10, Vec3(0, -1, 0), Vec3(0, -0.3, 0)},
            temple(Vec3(-1, 0, 0))}),
      {"brow", "forehead", "cheek_l", "cheek_r"});
  // Nose wrinkler: the nose bridge up, the inner brows down, the upper lip up.
  set("AU09_nose_wrinkler",
      Sum(Symmetric({{0, 14, nt - 5, bt - 5, 10, Vec3(0, 2.5, 0.5), Vec3(0, 1.5, 0.3)},
                     {0, 30, bt - 3, bt + 25, 8, Vec3(-0.5, -1.5, 0), Vec3(-0.5, -1.5, 0)}}),
          both({{10, 45, mt + 5, nt + 10, 12, Vec3(0, 1.5, 0.5), Vec3(0, 1.5, 0.5)}})),
      {"forehead", "mouth", "cheek_l", "cheek_r", "eye_l", "eye_r"});
  set("AU10_upper_lip_raiser",
      Sum(Symmetric({{0, 50, mt, nt + 5, 12, Vec3(0, 3, 1), Vec3(0, 1.5, 0.5)}}),
          both({{5, 20, nt, et, 10, Vec3(0, 0.8, 0), Vec3(0, 0.8, 0)}})),
      {"cheek_l", "cheek_r"});
  set("AU11_nasolabial_deepener",
      both({{15, 60, mt, et - 8, 12, Vec3(0.5, 2, 1.5), Vec3(0.5, 2, 1.5)}}), {"nose"});
  set("AU14_dimpler", both({{15, 70, ct, nt, 12, Vec3(1, 0, -1), Vec3(1, 0, -1)}}),
      {"cheek_l", "cheek_r", "chin"});
  set("AU16_lower_lip_depressor",
      Symmetric({{0, 40, ct - 20, mt - 2, 12, Vec3(0, -1, 0), Vec3(0.5, -3, 1)}}), {"jaw"});
  set("AU17_chin_raiser",
      Symmetric({{0, 45, ct - 25, mt - 3, 12, Vec3(0, 2, 1.5), Vec3(0, 1.5, 1)}}), {"jaw"});
  // Pucker and funnel draw the whole mouth region in.
  set("AU18_lip_puckerer",
      Symmetric({{0, 50, ct, nt, 15, Vec3(-2, 0, 1.5), Vec3(-2, 0, 1.5)}}),
      {"cheek_l", "cheek_r", "chin"});
  set("AU22_lip_funneler",
      Symmetric({{0, 45, ct + 5, nt, 15, Vec3(-1.2, 0, 2), Vec3(-1.2, 0, 2)}}),
      {"cheek_l", "cheek_r", "chin"});
  set("AU23_lip_tightener",
      Symmetric({{0, 40, mt - 15, mt + 15, 12, Vec3(-0.8, 0, -0.5), Vec3(-0.8, 0, -0.5)}}),
      {});
  set("AU24_lip_pressor",
      Symmetric({{0, 40, ct, nt, 12, Vec3(0, 1.5, 0), Vec3(0, -1, 0)}}), {});
  set("AU34_cheek_puff",
      both({{20, 95, ct, et - 8, 15, Vec3::Zero(), Vec3::Zero(), 3.5}}), {"jaw", "chin"});
  set("AU26_jaw_drop",
      Sum(Symmetric({{0, 100, ct - 30, et - 5, 15, Vec3(0, -2.5, 0), Vec3(0, -0.5, 0)}}),
          both({temple(Vec3(0, -0.5, 0.3))})),
      {"cheek_l", "cheek_r", "forehead"});
  set("AU27_mouth_stretch",
      Sum(Symmetric({{0, 90, ct - 30, nt + 5, 15, Vec3(0, -2, 0), Vec3(0, -0.5, 0)}}),
          both({temple(Vec3(0, -0.4, 0.3))})),
      {"cheek_l", "cheek_r", "chin", "forehead"});
  // Jaw forward: the whole lower face, most at the chin.
  set("AU29_jaw_thrust",
      Symmetric({{0, 110, ct - 40, nt + 10, 15, Vec3(0, 0, 4), Vec3(0, 0, 1)}}),
      {"mouth", "cheek_l", "cheek_r"});
  for (size_t k = 0; k < catalog->units.size(); ++k) {
    HMC_CHECK_MSG(catalog->broad[k] != nullptr,
                  "broad rig: no region for unit " + catalog->units[k].name);
  }
}

}  // namespace hmc
