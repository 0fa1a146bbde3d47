// A small synthetic actor for the unit tests and benchmarks of indexing/ and
// blending/ (header-only, so it adds nothing to the libraries): a bumpy
// grid face with UVs, markers on vertices and inside triangles, smooth random
// expression shapes with nonlinear in-betweens, and a jaw rig whose shapes
// carry their own jaw rotation. Deterministic by seed.
#pragma once

#include <cmath>
#include <random>
#include <string>

#include "core/actor.h"
#include "core/jaw.h"

namespace hmc::testing {

struct LgiTestActorOptions {
  int seed = 1;
  int grid = 24;          // vertices per side
  int markers_side = 4;   // markers per side of the marker lattice
  int base_shapes = 6;    // random expressions (each adds an in-between)
  bool jaw = true;        // jaw rig; half the shapes open the jaw
};

inline Actor MakeLgiTestActor(const LgiTestActorOptions& o) {
  std::mt19937 rng(o.seed);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  Actor actor;
  actor.name = "lgi_test_" + std::to_string(o.seed);
  actor.content_hash = 0x1234 + o.seed;
  const int n = o.grid;
  TriMesh& m = actor.neutral;
  m.V.resize(n * n, 3);
  m.UV.resize(n * n, 2);
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const double u = double(i) / (n - 1), v = double(j) / (n - 1);
      const double x = 100 * u - 50, y = 100 * v - 50;
      m.V.row(j * n + i) << x, y, 20 * std::exp(-(x * x + y * y) / 2000.0);
      m.UV.row(j * n + i) << u, v;
    }
  }
  m.F.resize(2 * (n - 1) * (n - 1), 3);
  int f = 0;
  for (int j = 0; j + 1 < n; ++j) {
    for (int i = 0; i + 1 < n; ++i) {
      const int a = j * n + i, b = a + 1, c = a + n, d = c + 1;
      m.F.row(f++) << a, b, d;
      m.F.row(f++) << a, d, c;
    }
  }
  m.FUV = m.F;

  // Markers: a jittered lattice, alternately on a vertex and in a triangle.
  for (int q = 0; q < o.markers_side; ++q) {
    for (int p = 0; p < o.markers_side; ++p) {
      Marker mk;
      mk.name = "m" + std::to_string(q * o.markers_side + p);
      const double fu = (p + 0.5 + 0.3 * (uni(rng) - 0.5)) / o.markers_side;
      const double fv = (q + 0.5 + 0.3 * (uni(rng) - 0.5)) / o.markers_side;
      const int i = std::min(n - 2, static_cast<int>(fu * (n - 1)));
      const int j = std::min(n - 2, static_cast<int>(fv * (n - 1)));
      if ((p + q) % 2 == 0) {
        mk.vertex = j * n + i;
        mk.point = SurfacePointAtVertex(m.F, mk.vertex);
      } else {
        mk.point.face = 2 * (j * (n - 1) + i);
        const double b1 = 0.1 + 0.5 * uni(rng), b2 = 0.1 + 0.3 * uni(rng);
        mk.point.bary = Vec3(1 - b1 - b2, b1, b2);
      }
      actor.markers.push_back(mk);
    }
  }

  if (o.jaw) {
    JawRig rig;
    rig.pivot = Vec3(0, -10, -60);
    rig.weights.resize(n * n);
    for (int v = 0; v < n * n; ++v) {
      const double t = std::clamp((-5 - m.V(v, 1)) / 20.0, 0.0, 1.0);
      rig.weights[v] = t * t * (3 - 2 * t);
    }
    actor.jaw_rig = rig;
  }

  // Expressions: two Gaussian bumps with random 3D amplitudes plus a fine
  // ripple; the in-between at 50% has a different ripple (nonlinear).
  auto expression = [&](double scale, const Vec3& c1, const Vec3& a1,
                        const Vec3& c2, const Vec3& a2, double phase) {
    MatX3d d(n * n, 3);
    for (int v = 0; v < n * n; ++v) {
      const Vec3 x = m.V.row(v).transpose();
      const double g1 = std::exp(-(x - c1).squaredNorm() / 600.0);
      const double g2 = std::exp(-(x - c2).squaredNorm() / 900.0);
      const double ripple =
          0.3 * scale * scale * std::sin(0.4 * x[0] + phase) * g1;
      d.row(v) = (scale * (g1 * a1 + g2 * a2) + Vec3(0, 0, ripple)).transpose();
    }
    return d;
  };
  for (int s = 0; s < o.base_shapes; ++s) {
    auto rnd_c = [&] {
      return Vec3(100 * uni(rng) - 50, 100 * uni(rng) - 50, 0);
    };
    auto rnd_a = [&] {
      return Vec3(8 * uni(rng) - 4, 8 * uni(rng) - 4, 8 * uni(rng) - 4);
    };
    const Vec3 c1 = rnd_c(), a1 = rnd_a(), c2 = rnd_c(), a2 = rnd_a();
    const double phase = 6 * uni(rng);
    const double open = (o.jaw && s % 2 == 1) ? 4 + 10 * uni(rng) : 0.0;
    for (double scale : {1.0, 0.5}) {
      Shape shape;
      shape.name = "e" + std::to_string(s) + (scale == 1.0 ? "_100" : "_50");
      shape.jaw.open_deg = open * scale;
      MatX3d x = m.V + expression(scale, c1, a1, c2, a2, phase);
      if (o.jaw) x = Skin(*actor.jaw_rig, shape.jaw, x);
      shape.displacement = x - m.V;
      actor.shapes.push_back(shape);
    }
  }
  return actor;
}

}  // namespace hmc::testing
