// Screen-space subdivision of a mesh seen through a fisheye lens, for the
// footage renderer (synth/footage.h, docs/footage.md): a straight triangle
// edge images as a curve under the lens model (core/camera.h), so each projected
// triangle is split until every edge's chord is within a tolerance of the
// projected edge (midpoint sagitta). The split decision depends on the edge
// alone, so neighbours split shared edges alike and no T-junction cracks
// appear.
#pragma once

#include <cmath>
#include <cstdint>
#include <vector>

#include "core/camera.h"
#include "core/mesh.h"

namespace hmc {

// The Kannala-Brandt projection of Camera::Project, inlined for the
// renderer's hot loops; `max_theta` (the camera's MaxTheta) replaces the
// per-point monotonicity check. Other lens models go through
// Camera::Project itself.
struct FastFisheye {
  double fx, fy, cx, cy, k1, k2, k3, k4, max_theta, width, height;
  Camera camera;
  explicit FastFisheye(const Camera& c)
      : fx(c.fx), fy(c.fy), cx(c.cx), cy(c.cy), k1(c.k[0]), k2(c.k[1]), k3(c.k[2]),
        k4(c.k[3]), max_theta(c.MaxTheta()), width(c.width), height(c.height), camera(c) {}
  bool Project(const Vec3& p, Vec2* pixel) const {
    if (camera.model != CameraModel::kKannalaBrandt) return camera.Project(p, pixel);
    const double r = std::sqrt(p.x() * p.x() + p.y() * p.y());
    double scale;
    if (r <= 1e-8 * p.z()) {
      if (!(p.z() > 0)) return false;
      scale = 1.0 / p.z();
    } else {
      if (!(r > 0)) return false;
      const double theta = std::atan2(r, p.z());
      if (!(theta < max_theta)) return false;
      const double t2 = theta * theta;
      scale = theta * (1 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4)))) / r;
    }
    (*pixel)[0] = fx * scale * p.x() + cx;
    (*pixel)[1] = fy * scale * p.y() + cy;
    return true;
  }
};

// What the triangle subdivision did for one view.
struct SubdivisionStats {
  int64_t input_triangles = 0;   // front-facing triangles projected
  int64_t split_triangles = 0;   // of which were subdivided
  int64_t output_triangles = 0;  // triangles rasterized
  double max_edge_error_px = 0;  // largest midpoint sagitta of a rasterized edge
};

// Screen-space triangles of the fisheye projection of a mesh.
struct FisheyeTriangles {
  MatX3d screen;          // N x 3: x_px, y_px, distance from the camera (mm)
  MatX3i F;               // T x 3 rows of screen
  std::vector<int> face;  // T: the mesh triangle each came from
  SubdivisionStats stats;
};

// Projects the triangles of (X_cam, F) that face the camera and subdivides
// them until the chord of every edge is within `max_edge_error_px` of the
// projected edge's midpoint. X_cam: V x 3 in the camera frame (mm).
FisheyeTriangles SubdivideForFisheye(const FisheyeCamera& camera,
                                     const MatX3d& X_cam, const MatX3i& F,
                                     double max_edge_error_px);

}  // namespace hmc
