#include "core/raster.h"

#include <cmath>
#include <limits>

#include "core/error.h"
#include "core/parallel.h"

namespace hmc {
namespace {

// floor(a / kFixedOne) and ceil(a / kFixedOne) for any sign.
int64_t FloorPixel(int64_t a) {
  return a >= 0 ? a / kFixedOne : -((-a + kFixedOne - 1) / kFixedOne);
}
int64_t CeilPixel(int64_t a) { return -FloorPixel(-a); }

}  // namespace

void TriangleSetup::EdgesAt(int px, int py, int64_t w[3]) const {
  const int64_t fx = px * kFixedOne;
  const int64_t fy = py * kFixedOne;
  for (int i = 0; i < 3; ++i) w[i] = a[i] * fx + b[i] * fy + c[i];
}

bool SetupTriangle(const double x[3], const double y[3], CullMode cull,
                   TriangleSetup* setup) {
  int64_t fx[3];
  int64_t fy[3];
  for (int i = 0; i < 3; ++i) {
    if (!(std::abs(x[i]) <= kMaxCoordinatePx &&
          std::abs(y[i]) <= kMaxCoordinatePx)) {
      return false;  // also rejects NaN
    }
    fx[i] = std::llround(x[i] * kFixedOne);
    fy[i] = std::llround(y[i] * kFixedOne);
  }
  // Twice the signed area; positive when clockwise on screen (y down).
  const int64_t area2 =
      (fx[2] - fx[1]) * (fy[0] - fy[1]) - (fy[2] - fy[1]) * (fx[0] - fx[1]);
  if (area2 == 0) return false;
  if (area2 < 0 && cull == CullMode::kCounterClockwise) return false;
  const int64_t sign = area2 > 0 ? 1 : -1;
  for (int i = 0; i < 3; ++i) {
    const int j = (i + 1) % 3;
    const int k = (i + 2) % 3;
    // w_i(p) = (x_k - x_j)(p_y - y_j) - (y_k - y_j)(p_x - x_j), times sign.
    setup->a[i] = -sign * (fy[k] - fy[j]);
    setup->b[i] = sign * (fx[k] - fx[j]);
    setup->c[i] = -(setup->a[i] * fx[j] + setup->b[i] * fy[j]);
    // Top-left rule: a pixel centre exactly on an edge belongs to the
    // triangle whose interior lies right of the edge (left edge, a > 0) or
    // below a horizontal edge (top edge, a == 0, b > 0). The neighbour
    // across the edge has the opposite normal, so exactly one owns it.
    const bool top_left =
        setup->a[i] > 0 || (setup->a[i] == 0 && setup->b[i] > 0);
    setup->bias[i] = top_left ? 0 : -1;
  }
  setup->area2 = area2 * sign;
  setup->min_x = static_cast<int>(CeilPixel(std::min({fx[0], fx[1], fx[2]})));
  setup->max_x = static_cast<int>(FloorPixel(std::max({fx[0], fx[1], fx[2]})));
  setup->min_y = static_cast<int>(CeilPixel(std::min({fy[0], fy[1], fy[2]})));
  setup->max_y = static_cast<int>(FloorPixel(std::max({fy[0], fy[1], fy[2]})));
  return setup->min_x <= setup->max_x && setup->min_y <= setup->max_y;
}

int RasterBuffer::NumCovered() const {
  int count = 0;
  for (int32_t t : triangle) count += t >= 0;
  return count;
}

namespace {

// Triangle setups binned into square tiles (the unit of parallel work), in
// triangle index order, so each tile sees its triangles in the same order
// whatever the thread count.
struct TiledTriangles {
  std::vector<TriangleSetup> setups;
  std::vector<std::vector<int32_t>> bins;
  int tile = 32;
  int tiles_x = 0;
};

TiledTriangles SetupAndBin(const MatX3d& screen, const Eigen::VectorXd& inv_w,
                           const MatX3i& F, const RasterOptions& options,
                           int width, int height) {
  TiledTriangles out;
  const bool perspective = inv_w.size() > 0;
  HMC_CHECK(!perspective || inv_w.size() == screen.rows());
  const int num_triangles = static_cast<int>(F.rows());
  out.setups.resize(num_triangles);
  std::vector<char> valid(num_triangles, 0);
  ParallelFor(
      0, num_triangles,
      [&](int64_t t) {
        double x[3];
        double y[3];
        for (int i = 0; i < 3; ++i) {
          const int v = F(t, i);
          if (v < 0 || v >= screen.rows()) return;
          if (!std::isfinite(screen(v, 2))) return;
          if (perspective && !(inv_w[v] > 0 && std::isfinite(inv_w[v]))) {
            return;
          }
          x[i] = screen(v, 0);
          y[i] = screen(v, 1);
        }
        valid[t] = SetupTriangle(x, y, options.cull, &out.setups[t]);
      },
      256);
  out.tile = std::max(8, options.tile_size);
  const int tile = out.tile;
  out.tiles_x = (width + tile - 1) / tile;
  const int tiles_y = (height + tile - 1) / tile;
  out.bins.resize(static_cast<size_t>(out.tiles_x) * tiles_y);
  for (int t = 0; t < num_triangles; ++t) {
    if (!valid[t]) continue;
    const TriangleSetup& s = out.setups[t];
    if (s.max_x < 0 || s.max_y < 0 || s.min_x >= width || s.min_y >= height) {
      continue;
    }
    const int tx0 = std::max(0, s.min_x) / tile;
    const int ty0 = std::max(0, s.min_y) / tile;
    const int tx1 = std::min(width - 1, s.max_x) / tile;
    const int ty1 = std::min(height - 1, s.max_y) / tile;
    for (int ty = ty0; ty <= ty1; ++ty) {
      for (int tx = tx0; tx <= tx1; ++tx) {
        out.bins[ty * out.tiles_x + tx].push_back(t);
      }
    }
  }
  return out;
}

// Calls fn(px, py, b, depth) for every pixel of tile `bin` covered by a
// triangle, in triangle order: b the perspective-correct barycentrics,
// depth the interpolated depth. Both rasterizers share it, so they agree
// on every depth comparison.
template <typename Fn>
void ForEachTileFragment(const TiledTriangles& tiled, int64_t bin, int width,
                         int height, const MatX3d& screen,
                         const Eigen::VectorXd& inv_w, const MatX3i& F,
                         const Fn& fn) {
  const bool perspective = inv_w.size() > 0;
  const int tile = tiled.tile;
  const int tx = static_cast<int>(bin % tiled.tiles_x);
  const int ty = static_cast<int>(bin / tiled.tiles_x);
  const int x0 = tx * tile;
  const int y0 = ty * tile;
  const int x1 = std::min(width, x0 + tile) - 1;
  const int y1 = std::min(height, y0 + tile) - 1;
  for (int32_t t : tiled.bins[bin]) {
    const TriangleSetup& s = tiled.setups[t];
    const double inv_area = 1.0 / static_cast<double>(s.area2);
    double iw[3] = {1.0, 1.0, 1.0};
    double z[3];
    for (int i = 0; i < 3; ++i) {
      if (perspective) iw[i] = inv_w[F(t, i)];
      z[i] = screen(F(t, i), 2);
    }
    ForEachCoveredPixel(s, x0, y0, x1, y1,
                        [&](int px, int py, const int64_t w[3]) {
      double q[3];
      double sum = 0.0;
      for (int i = 0; i < 3; ++i) {
        q[i] = static_cast<double>(w[i]) * inv_area * iw[i];
        sum += q[i];
      }
      const Eigen::Vector3d b(q[0] / sum, q[1] / sum, q[2] / sum);
      const double depth = b[0] * z[0] + b[1] * z[1] + b[2] * z[2];
      fn(px, py, t, b, depth);
    });
  }
}

}  // namespace

RasterBuffer Rasterize(const MatX3d& screen, const Eigen::VectorXd& inv_w,
                       const MatX3i& F, const RasterOptions& options) {
  RasterBuffer buffer;
  buffer.width = std::max(0, options.width);
  buffer.height = std::max(0, options.height);
  const size_t num_pixels =
      static_cast<size_t>(buffer.width) * static_cast<size_t>(buffer.height);
  buffer.depth.assign(num_pixels, std::numeric_limits<double>::infinity());
  buffer.triangle.assign(num_pixels, -1);
  buffer.bary.assign(num_pixels, Eigen::Vector3d::Zero());
  if (num_pixels == 0 || F.rows() == 0) return buffer;
  const TiledTriangles tiled =
      SetupAndBin(screen, inv_w, F, options, buffer.width, buffer.height);
  // Each tile owns its pixels: no two threads write the same pixel.
  ParallelFor(0, static_cast<int64_t>(tiled.bins.size()), [&](int64_t bin) {
    ForEachTileFragment(
        tiled, bin, buffer.width, buffer.height, screen, inv_w, F,
        [&](int px, int py, int32_t t, const Eigen::Vector3d& b, double depth) {
          const int index = buffer.Index(px, py);
          if (depth < buffer.depth[index]) {
            buffer.depth[index] = depth;
            buffer.triangle[index] = t;
            buffer.bary[index] = b;
          }
        });
  });
  return buffer;
}

void RasterizeTriangleIds(const MatX3d& screen, const Eigen::VectorXd& inv_w,
                          const MatX3i& F, const RasterOptions& options,
                          std::vector<int32_t>* triangle) {
  const int width = std::max(0, options.width);
  const int height = std::max(0, options.height);
  triangle->assign(static_cast<size_t>(width) * static_cast<size_t>(height), -1);
  if (triangle->empty() || F.rows() == 0) return;
  const TiledTriangles tiled = SetupAndBin(screen, inv_w, F, options, width, height);
  const int tile = tiled.tile;
  ParallelFor(0, static_cast<int64_t>(tiled.bins.size()), [&](int64_t bin) {
    // The z-buffer lives only for the tile (cache resident).
    std::vector<double> depth(static_cast<size_t>(tile) * tile,
                              std::numeric_limits<double>::infinity());
    const int x0 = static_cast<int>(bin % tiled.tiles_x) * tile;
    const int y0 = static_cast<int>(bin / tiled.tiles_x) * tile;
    ForEachTileFragment(
        tiled, bin, width, height, screen, inv_w, F,
        [&](int px, int py, int32_t t, const Eigen::Vector3d&, double z) {
          double& nearest = depth[(py - y0) * tile + (px - x0)];
          if (z < nearest) {
            nearest = z;
            (*triangle)[static_cast<size_t>(py) * width + px] = t;
          }
        });
  });
}

}  // namespace hmc
