// The procedural neutral face of the synthetic actor: a (u, v) grid mapped to
// a head-shaped surface, with the landmarks the action units and markers are
// placed by, and the jaw rig.
//
// Geometry: each grid vertex has face-plane coordinates (s, t) in mm, linear
// in its UV: s is arc length around the head at a reference radius (+s to the
// actor's left), t is height (= head-space y). The surface is a radial height
// field around the vertical axis,
//   p(s, t) = (r sin(theta), t, r cos(theta)),  theta = s / kArcRadius,
//   r = base ellipse(theta; half-width a(t), depth b(t)) + features(s, t),
// where the features (brow ridge, eye sockets, eyeballs, lids, nose, cheeks,
// lips, chin, ...) are smooth bumps in (s, t). The triangles of the mouth slit
// are removed so upper and lower lips are separate surfaces.
#pragma once

#include <cstdint>
#include <vector>

#include "core/jaw.h"
#include "core/mesh.h"
#include "core/types.h"

namespace hmc {

// Proportions of one synthetic face; the seed varies them a little.
struct FaceProportions {
  double width_scale = 1.0;   // scales the head's half-width profile
  double depth_scale = 1.0;   // scales the head's front depth profile
  double eye_s = 33.0;        // eye centre, |s| (mm)
  double eye_t = 13.0;        // eye centre height (mm)
  double brow_t = 34.0;       // brow ridge height (mm)
  double nose_tip_t = -22.0;  // nose tip height (mm)
  double nose_height = 1.0;   // scales how far the nose protrudes
  double mouth_t = -51.0;     // mouth slit height (mm), snapped to the grid
  double mouth_half_width = 26.0;  // half the mouth width (mm)
  double lip_fullness = 1.0;  // scales lip volume
  double chin_t = -84.0;      // chin centre height (mm)
  double detail_phase = 0.0;  // phase of the wrinkle patterns (rad)
};

// Draws proportions from `seed`; `jitter` is the relative spread (0: the
// average face).
FaceProportions DrawFaceProportions(uint64_t seed, double jitter);

// Extent of the grid in face-plane coordinates.
constexpr double kArcRadius = 85.0;     // mm; s = theta * kArcRadius
constexpr double kThetaMaxDeg = 110.0;  // u in [0,1] <-> theta in +-110 deg
constexpr double kTMin = -130.0;        // bottom row height (neck), mm
constexpr double kTMax = 100.0;         // top row height (hairline), mm

struct FaceMesh {
  TriMesh mesh;        // neutral, UVs = grid (u, v), one UV per vertex
  MatX2d st;           // V x 2 face-plane coordinates (s, t) (mm)
  int grid_u = 0;      // columns
  int grid_v = 0;      // rows
  std::vector<int> quad_face;  // (grid_v-1) x (grid_u-1): first triangle of
                               // each grid quad, -1 for the removed mouth slit
  FaceProportions proportions;  // mouth_t snapped between two grid rows
  double row_spacing = 0.0;     // mm between grid rows
  JawRig jaw_rig;               // pivot near the ears, smooth weights
};

// Builds the neutral face on a grid_u x grid_v vertex grid (>= 24 x 20).
FaceMesh BuildFaceMesh(const FaceProportions& proportions, int grid_u,
                       int grid_v);

// Radial offset of the neutral surface from the base ellipse at (s, t) (mm).
double FaceFeatureOffset(const FaceProportions& p, double s, double t);

// Face-plane coordinates <-> UV.
Vec2 UVFromFacePlane(const Vec2& st);
Vec2 FacePlaneFromUV(const Vec2& uv);

// The surface point of the mesh at face-plane coordinates `st`: the grid
// triangle containing it and barycentrics. Returns face -1 if `st` is outside
// the grid or falls in the removed mouth slit.
SurfacePoint FaceSurfacePoint(const FaceMesh& face, const Vec2& st);

// Smooth compact bump: (1 - q)^3 for q = (ds/rs)^2 + (dt/rt)^2 < 1, else 0.
inline double CompactBump(double ds, double dt, double rs, double rt) {
  const double q = (ds / rs) * (ds / rs) + (dt / rt) * (dt / rt);
  if (q >= 1.0) return 0.0;
  const double m = 1.0 - q;
  return m * m * m;
}

// Hermite smoothstep of x from edge0 to edge1 (either order), in [0,1].
double SmoothStep(double edge0, double edge1, double x);

}  // namespace hmc
