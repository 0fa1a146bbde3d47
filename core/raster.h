// A small software rasterizer: triangles in screen space with a z-buffer.
//
// Two layers, kept apart so other renderers (the fisheye footage renderer)
// reuse the core and bring their own shading:
//  1. Triangle setup and coverage (TriangleSetup, ForEachCoveredPixel):
//     vertices snapped to 1/256 px fixed point, integer edge functions, the
//     top-left fill rule. Exact integer arithmetic makes coverage watertight:
//     a pixel centre on an edge shared by two triangles belongs to exactly
//     one of them, also at shared vertices.
//  2. Rasterize(): a visibility buffer (per pixel: nearest triangle, its
//     perspective-correct barycentrics and depth), tiled and parallel over
//     tiles. Shading reads the buffer afterwards (InterpolateAt).
//
// Conventions: pixel centres at integer coordinates (OpenCV: the centre of
// the top-left pixel is (0, 0)); x right, y down; a pixel is covered when its
// centre is inside the triangle. Attributes are interpolated perspective-
// correctly: with screen-space barycentrics s_i and per-vertex 1/w_i,
// b_i = s_i / w_i / sum_j (s_j / w_j) (w = camera depth for a pinhole
// camera, 1 for an orthographic one, which makes it affine).
// Triangles are not clipped: the caller drops triangles that cross the
// camera plane; vertex coordinates beyond +-kMaxCoordinatePx are rejected.
#pragma once

#include <algorithm>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "core/types.h"

namespace hmc {

constexpr int kSubpixelBits = 8;            // 1/256 px vertex precision
constexpr int64_t kFixedOne = int64_t{1} << kSubpixelBits;  // 1 px
constexpr double kMaxCoordinatePx = 1 << 20;  // keeps edge functions in int64

enum class CullMode {
  kNone,  // both windings drawn
  // Drop triangles that are counter-clockwise on screen (y down). A mesh
  // wound counter-clockwise seen from outside (core/mesh.h) appears
  // clockwise in pixel coordinates when it faces the camera, so this drops
  // back faces.
  kCounterClockwise,
};

// A triangle ready for coverage tests. Edge i is opposite corner i; its
// edge function w_i(p) = a_i p_x + b_i p_y + c_i (p in fixed point) is twice
// the area of (p, corner i+1, corner i+2), signed so that it is positive
// inside whatever the winding. Corners keep the caller's order: w_i / area2
// is the screen-space barycentric of corner i.
struct TriangleSetup {
  int64_t a[3];     // edge-function coefficients (fixed point)
  int64_t b[3];
  int64_t c[3];
  int64_t bias[3];  // 0 if edge i is a top or left edge, else -1
  int64_t area2;    // w_0 + w_1 + w_2 everywhere (> 0)
  int min_x, min_y, max_x, max_y;  // pixel-centre bounding box (inclusive)

  // Edge functions at pixel centre (px, py).
  void EdgesAt(int px, int py, int64_t w[3]) const;
};

// Prepares a triangle with corners (x_i, y_i) in pixels. Returns false for
// degenerate (zero-area after snapping), culled, non-finite or out-of-range
// triangles, and ones that cover no pixel centre of their bounding box.
bool SetupTriangle(const double x[3], const double y[3], CullMode cull,
                   TriangleSetup* setup);

// Calls fn(px, py, w) for every pixel centre in [x0, x1] x [y0, y1]
// (inclusive) covered by `setup`, row by row; w: the three edge functions
// (integers; divide by area2 for screen-space barycentrics).
template <typename Fn>
void ForEachCoveredPixel(const TriangleSetup& setup, int x0, int y0, int x1,
                         int y1, const Fn& fn) {
  x0 = std::max(x0, setup.min_x);
  y0 = std::max(y0, setup.min_y);
  x1 = std::min(x1, setup.max_x);
  y1 = std::min(y1, setup.max_y);
  if (x0 > x1 || y0 > y1) return;
  int64_t row[3];
  setup.EdgesAt(x0, y0, row);
  for (int py = y0; py <= y1; ++py) {
    int64_t w[3] = {row[0], row[1], row[2]};
    for (int px = x0; px <= x1; ++px) {
      if (((w[0] + setup.bias[0]) | (w[1] + setup.bias[1]) |
           (w[2] + setup.bias[2])) >= 0) {
        fn(px, py, w);
      }
      for (int i = 0; i < 3; ++i) w[i] += setup.a[i] * kFixedOne;
    }
    for (int i = 0; i < 3; ++i) row[i] += setup.b[i] * kFixedOne;
  }
}

struct RasterOptions {
  int width = 0;   // image size (px)
  int height = 0;
  CullMode cull = CullMode::kNone;
  int tile_size = 32;  // px; tiles are the unit of parallel work
};

// The visibility buffer: per pixel (row-major, index y * width + x) the
// nearest triangle and where on it the pixel centre lies.
struct RasterBuffer {
  int width = 0;
  int height = 0;
  std::vector<double> depth;          // interpolated depth; +inf where empty
  std::vector<int32_t> triangle;      // row of F; -1 where empty
  std::vector<Eigen::Vector3d> bary;  // perspective-correct barycentrics of
                                      // the triangle's corners 0, 1, 2

  int Index(int x, int y) const { return y * width + x; }
  bool Covered(int index) const { return triangle[index] >= 0; }
  int NumCovered() const;
};

// Rasterizes triangles F with a z-buffer (smaller depth is nearer; on equal
// depth the lower triangle index wins, so the result does not depend on the
// thread count). Triangles with a negative or out-of-range index are skipped.
// screen: V x 3 (x_px, y_px, depth); depth is interpolated perspective-
//         correctly like every attribute (use the camera-space distance
//         along the axis, or any monotonic stand-in for orthographic views).
// inv_w:  V per-vertex 1/w (1/camera depth for a pinhole camera); empty
//         means affine interpolation (orthographic).
// F:      F x 3 corner indices.
RasterBuffer Rasterize(const MatX3d& screen, const Eigen::VectorXd& inv_w,
                       const MatX3i& F, const RasterOptions& options);

// The triangle-id layer of Rasterize() alone: per pixel (row-major) the
// row of F that Rasterize() would report, or -1. For renderers that
// recompute the surface per pixel (synth/footage.h ray-intersects the seen
// triangle), the full buffer's depth and barycentrics cost memory traffic
// for nothing; here the z-buffer lives per tile. `triangle` is resized to
// width * height.
void RasterizeTriangleIds(const MatX3d& screen, const Eigen::VectorXd& inv_w,
                          const MatX3i& F, const RasterOptions& options,
                          std::vector<int32_t>* triangle);

// Interpolates a per-vertex attribute (V x K, any K) at covered pixel
// `index` of `buffer` rasterized from triangles F. Returns 1 x K.
template <typename Derived>
Eigen::Matrix<typename Derived::Scalar, 1, Derived::ColsAtCompileTime>
InterpolateAt(const RasterBuffer& buffer, int index, const MatX3i& F,
              const Eigen::MatrixBase<Derived>& attribute) {
  const int t = buffer.triangle[index];
  const Eigen::Vector3d& b = buffer.bary[index];
  using Scalar = typename Derived::Scalar;
  return Scalar(b[0]) * attribute.row(F(t, 0)) +
         Scalar(b[1]) * attribute.row(F(t, 1)) +
         Scalar(b[2]) * attribute.row(F(t, 2));
}

}  // namespace hmc
