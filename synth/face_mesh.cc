#include "synth/face_mesh.h"

#include <algorithm>
#include <cmath>

#include "core/error.h"
#include "core/parallel.h"
#include "synth/synth_random.h"

namespace hmc {
namespace {

constexpr double kDegToRad = M_PI / 180.0;

// Cubic Hermite interpolation through (x_k, y_k) with centred-difference
// tangents; constant beyond the ends. Smooth profiles from a few numbers.
class Profile {
 public:
  Profile(std::vector<double> x, std::vector<double> y)
      : x_(std::move(x)), y_(std::move(y)) {}

  double operator()(double x) const {
    const int n = static_cast<int>(x_.size());
    if (x <= x_.front()) return y_.front();
    if (x >= x_.back()) return y_.back();
    int k = 0;
    while (x > x_[k + 1]) ++k;
    const double h = x_[k + 1] - x_[k];
    const double f = (x - x_[k]) / h;
    const double m0 = Slope(k, n) * h, m1 = Slope(k + 1, n) * h;
    const double f2 = f * f, f3 = f2 * f;
    return (2 * f3 - 3 * f2 + 1) * y_[k] + (f3 - 2 * f2 + f) * m0 +
           (-2 * f3 + 3 * f2) * y_[k + 1] + (f3 - f2) * m1;
  }

 private:
  double Slope(int k, int n) const {
    if (k == 0 || k == n - 1) return 0.0;
    return (y_[k + 1] - y_[k - 1]) / (x_[k + 1] - x_[k - 1]);
  }
  std::vector<double> x_, y_;
};

double Gauss(double ds, double dt, double rs, double rt) {
  return std::exp(-0.5 * ((ds / rs) * (ds / rs) + (dt / rt) * (dt / rt)));
}

double Gauss1(double d, double r) { return std::exp(-0.5 * (d / r) * (d / r)); }

// (1 - x^2)^2 on |x| < 1: a window that fades smoothly to zero.
double Window(double x) {
  if (std::abs(x) >= 1.0) return 0.0;
  const double m = 1.0 - x * x;
  return m * m;
}

// Distance from (px, py) to the segment (ax, ay)-(bx, by).
double SegmentDistance(double px, double py, double ax, double ay, double bx,
                       double by) {
  const double dx = bx - ax, dy = by - ay;
  double f = ((px - ax) * dx + (py - ay) * dy) / (dx * dx + dy * dy);
  f = std::clamp(f, 0.0, 1.0);
  return std::hypot(px - (ax + f * dx), py - (ay + f * dy));
}

// Head half-width a(t) and front depth b(t) (mm), from the neck (t = -130)
// to the hairline (t = 100): throat, under the chin, chin, mouth, cheeks,
// eyes, brow, forehead sloping back.
const Profile& HalfWidthProfile() {
  static const Profile profile(
      {-130, -112, -100, -88, -70, -50, -25, 0, 20, 40, 60, 80, 100},
      {50, 50, 44, 42, 52, 60, 67, 71, 70, 68, 67, 64, 58});
  return profile;
}
const Profile& DepthProfile() {
  static const Profile profile(
      {-130, -112, -100, -88, -70, -50, -25, 0, 20, 40, 60, 80, 100},
      {48, 52, 70, 84, 87, 90, 91, 88, 86, 88, 85, 79, 70});
  return profile;
}

// Nose protrusion h and half-width w against tau = t - nose tip height.
const Profile& NoseHeightProfile() {
  static const Profile profile({-12, -9, -5, 0, 5, 20, 35, 50, 56},
                               {0, 8, 20, 23, 20, 13, 8, 2, 0});
  return profile;
}
const Profile& NoseWidthProfile() {
  static const Profile profile({-12, -9, -5, 0, 5, 20, 35, 50},
                               {15, 15, 14, 12, 10, 8.5, 8, 9});
  return profile;
}

}  // namespace

double SmoothStep(double edge0, double edge1, double x) {
  const double f = std::clamp((x - edge0) / (edge1 - edge0), 0.0, 1.0);
  return f * f * (3.0 - 2.0 * f);
}

FaceProportions DrawFaceProportions(uint64_t seed, double jitter) {
  SynthRandom rng = SynthRandom::Stream(seed, 1);
  // Symmetric draws in [-1, 1] scaled by the jitter; lengths vary by a few mm.
  auto vary = [&](double value, double spread_mm_or_rel, bool relative) {
    const double d = jitter / 0.04 * rng.Uniform(-1.0, 1.0) * spread_mm_or_rel;
    return relative ? value * (1.0 + d) : value + d;
  };
  FaceProportions p;
  p.width_scale = vary(1.0, 0.04, true);
  p.depth_scale = vary(1.0, 0.03, true);
  p.eye_s = vary(p.eye_s, 2.0, false);
  p.eye_t = vary(p.eye_t, 1.5, false);
  p.brow_t = vary(p.brow_t, 2.0, false);
  p.nose_tip_t = vary(p.nose_tip_t, 2.5, false);
  p.nose_height = vary(1.0, 0.1, true);
  p.mouth_t = vary(p.mouth_t, 2.0, false);
  p.mouth_half_width = vary(p.mouth_half_width, 2.0, false);
  p.lip_fullness = vary(1.0, 0.15, true);
  p.chin_t = vary(p.chin_t, 3.0, false);
  p.detail_phase = rng.Uniform(0.0, 2.0 * M_PI);
  return p;
}

double FaceFeatureOffset(const FaceProportions& p, double s, double t) {
  const double as = std::abs(s);
  double off = 0.0;
  // Forehead (frontal eminences), brow ridge, glabella, temples.
  off += 3.0 * Gauss(as - 25, t - 60, 18, 18);
  off += 6.0 * Gauss(as - 30, t - p.brow_t, 22, 7);
  off += 3.0 * Gauss(s, t - (p.brow_t - 4), 10, 8);
  off -= 4.0 * Gauss(as - 64, t - 42, 14, 20);
  // Eye socket, eyeball bulge, lids (upper lid, crease, fissure, lower lid).
  const double ex = as - p.eye_s, ey = t - p.eye_t;
  off -= 22.0 * Gauss(ex, ey + 1, 15, 11.5);
  off += 15.5 * Gauss(ex, ey, 10, 7.5);
  off += 3.0 * Gauss1(ey - 2.5, 2.0) * Window(ex / 14);
  off -= 2.0 * Gauss1(ey - 8.0, 1.5) * Window(ex / 15);
  off -= 4.0 * Gauss1(ey - 0.5, 1.0) * Window(ex / 13);
  off += 1.2 * Gauss1(ey + 2.8, 1.8) * Window(ex / 13);
  // Nose: bridge to tip profile, tip bulb, alae (wings), nostrils.
  const double tau = t - p.nose_tip_t;
  if (tau > -12 && tau < 56) {
    const double h = std::max(0.0, NoseHeightProfile()(tau)) * p.nose_height;
    off += h * Window(s / NoseWidthProfile()(tau));
  }
  off += 3.0 * Gauss(s, tau + 1, 6, 4.5) * p.nose_height;
  off += 7.0 * Gauss(as - 14, tau + 6, 5, 4.5);
  off -= 1.2 * Gauss1(std::hypot(as - 14, tau + 6) - 7.0, 1.2);
  off -= 4.0 * Gauss(as - 6.5, tau + 10, 3, 1.8);
  // Cheeks and cheekbones; a faint nasolabial line.
  off += 9.0 * Gauss(as - 46, t + 12, 22, 22);
  off += 5.0 * Gauss(as - 52, t - 2, 16, 9);
  off -= 1.0 * Gauss1(SegmentDistance(as, t, 17, p.nose_tip_t - 6,
                                      p.mouth_half_width + 5, p.mouth_t - 5),
                      2.5);
  // Muzzle, philtrum, lips, the lips rolling into the mouth slit, corners.
  const double mh = p.mouth_half_width, mt = p.mouth_t;
  off += 8.0 * Gauss(s, t - (mt - 3), 30, 24);
  off -= 1.2 * Gauss(s, t - (mt + 13), 3, 6);
  off += 0.8 * Gauss(as - 5, t - (mt + 13), 1.8, 6);
  const double wu = std::max(0.0, 1.0 - (s / mh) * (s / mh));
  off += 5.0 * p.lip_fullness * std::pow(wu, 0.7) *
         Gauss1(t - (mt + 4.0 + 0.8 * Gauss1(as - 5, 4)), 2.8);
  const double wl = std::max(0.0, 1.0 - (s / (mh - 2)) * (s / (mh - 2)));
  off += 6.0 * p.lip_fullness * std::pow(wl, 0.7) * Gauss1(t - (mt - 5), 3.2);
  off -= 5.0 * Gauss1(t - mt, 1.4) * Window(s / (mh + 2));
  off -= 2.5 * Gauss(as - mh, t - mt, 3.5, 3.5);
  // Mentolabial sulcus and chin.
  off -= 3.0 * Gauss(s, t - (mt - 16), 18, 3.5);
  off += 8.0 * Gauss(s, t - p.chin_t, 15, 10);
  return off;
}

Vec2 UVFromFacePlane(const Vec2& st) {
  const double s_max = kThetaMaxDeg * kDegToRad * kArcRadius;
  return Vec2(0.5 + st.x() / (2.0 * s_max), (st.y() - kTMin) / (kTMax - kTMin));
}

Vec2 FacePlaneFromUV(const Vec2& uv) {
  const double s_max = kThetaMaxDeg * kDegToRad * kArcRadius;
  return Vec2((uv.x() - 0.5) * 2.0 * s_max, kTMin + uv.y() * (kTMax - kTMin));
}

FaceMesh BuildFaceMesh(const FaceProportions& proportions, int grid_u,
                       int grid_v) {
  HMC_CHECK(grid_u >= 24 && grid_v >= 20);
  FaceMesh face;
  face.grid_u = grid_u;
  face.grid_v = grid_v;
  face.proportions = proportions;
  face.row_spacing = (kTMax - kTMin) / (grid_v - 1);
  FaceProportions& p = face.proportions;
  // Snap the mouth slit half-way between two rows: the quads between them
  // are removed, and the lips' edges are the rows on either side.
  const int slit_row = std::clamp(
      static_cast<int>(std::floor((p.mouth_t - kTMin) / face.row_spacing)), 1,
      grid_v - 3);
  p.mouth_t = kTMin + (slit_row + 0.5) * face.row_spacing;

  const int num_vertices = grid_u * grid_v;
  face.mesh.V.resize(num_vertices, 3);
  face.mesh.UV.resize(num_vertices, 2);
  face.st.resize(num_vertices, 2);
  ParallelFor(0, num_vertices, [&](int64_t v) {
    const int i = static_cast<int>(v % grid_u), j = static_cast<int>(v / grid_u);
    const Vec2 uv(static_cast<double>(i) / (grid_u - 1),
                  static_cast<double>(j) / (grid_v - 1));
    const Vec2 st = FacePlaneFromUV(uv);
    const double theta = st.x() / kArcRadius;
    const double a = HalfWidthProfile()(st.y()) * p.width_scale;
    const double b = DepthProfile()(st.y()) * p.depth_scale;
    const double sn = std::sin(theta), cs = std::cos(theta);
    const double r = a * b / std::sqrt(b * b * sn * sn + a * a * cs * cs) +
                     FaceFeatureOffset(p, st.x(), st.y());
    face.mesh.V.row(v) = Vec3(r * sn, st.y(), r * cs).transpose();
    face.mesh.UV.row(v) = uv.transpose();
    face.st.row(v) = st.transpose();
  }, 256);

  // Two counter-clockwise (seen from outside) triangles per grid quad,
  // except the mouth slit.
  const int quads_u = grid_u - 1, quads_v = grid_v - 1;
  face.quad_face.assign(quads_u * quads_v, -1);
  std::vector<Eigen::Vector3i> triangles;
  triangles.reserve(2 * quads_u * quads_v);
  for (int j = 0; j < quads_v; ++j) {
    for (int i = 0; i < quads_u; ++i) {
      const double s_centre = face.st(j * grid_u + i, 0) +
                              0.5 * (face.st(1, 0) - face.st(0, 0));
      if (j == slit_row && std::abs(s_centre) < p.mouth_half_width - 1.0) {
        continue;
      }
      const int a = j * grid_u + i, b = a + 1, c = a + grid_u + 1,
                d = a + grid_u;
      face.quad_face[j * quads_u + i] = static_cast<int>(triangles.size());
      triangles.emplace_back(a, b, c);
      triangles.emplace_back(a, c, d);
    }
  }
  face.mesh.F.resize(static_cast<int>(triangles.size()), 3);
  for (size_t f = 0; f < triangles.size(); ++f) {
    face.mesh.F.row(f) = triangles[f].transpose();
  }
  face.mesh.FUV = face.mesh.F;

  // Jaw rig: hinge in front of the ears, behind and above the mouth corners.
  // Weight 1 on the chin and lower lip, 0 on the upper lip and above; the
  // boundary runs from the slit along the mouth corners up towards the ears,
  // sharp across the slit (the lips are separate surfaces there) and soft
  // at the corners and on the cheeks.
  JawRig& rig = face.jaw_rig;
  rig.pivot = Vec3(0.0, -6.0, 6.0);
  rig.axes = Mat3::Identity();
  rig.weights.resize(num_vertices);
  const double mh = p.mouth_half_width;
  for (int v = 0; v < num_vertices; ++v) {
    const double as = std::abs(face.st(v, 0)), t = face.st(v, 1);
    const double boundary = p.mouth_t + 0.40 * std::max(0.0, as - mh);
    const double width =
        0.45 * face.row_spacing + 12.0 * SmoothStep(mh - 12, mh + 8, as);
    double w = SmoothStep(boundary + width, boundary - width, t);
    w *= 1.0 - SmoothStep(95.0, 125.0, as);
    w *= SmoothStep(kTMin, -108.0, t);
    rig.weights[v] = w;
  }
  return face;
}

SurfacePoint FaceSurfacePoint(const FaceMesh& face, const Vec2& st) {
  const Vec2 uv = UVFromFacePlane(st);
  const double fi = uv.x() * (face.grid_u - 1), fj = uv.y() * (face.grid_v - 1);
  SurfacePoint point;
  point.face = -1;
  if (!(fi >= 0 && fj >= 0 && fi <= face.grid_u - 1 && fj <= face.grid_v - 1)) {
    return point;
  }
  const int i = std::min(static_cast<int>(fi), face.grid_u - 2);
  const int j = std::min(static_cast<int>(fj), face.grid_v - 2);
  const double a = fi - i, b = fj - j;
  const int first = face.quad_face[j * (face.grid_u - 1) + i];
  if (first < 0) return point;
  if (a >= b) {  // triangle (00, 10, 11)
    point.face = first;
    point.bary = Vec3(1.0 - a, a - b, b);
  } else {       // triangle (00, 11, 01)
    point.face = first + 1;
    point.bary = Vec3(1.0 - b, a, b - a);
  }
  return point;
}

}  // namespace hmc
