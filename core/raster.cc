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
  const bool perspective = inv_w.size() > 0;
  HMC_CHECK(!perspective || inv_w.size() == screen.rows());

  // Set up every triangle (parallel, one slot each).
  const int num_triangles = static_cast<int>(F.rows());
  std::vector<TriangleSetup> setups(num_triangles);
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
        valid[t] = SetupTriangle(x, y, options.cull, &setups[t]);
      },
      256);

  // Bin triangles into tiles, in index order, so each tile later sees its
  // triangles in the same order whatever the thread count.
  const int tile = std::max(8, options.tile_size);
  const int tiles_x = (buffer.width + tile - 1) / tile;
  const int tiles_y = (buffer.height + tile - 1) / tile;
  std::vector<std::vector<int32_t>> bins(static_cast<size_t>(tiles_x) * tiles_y);
  for (int t = 0; t < num_triangles; ++t) {
    if (!valid[t]) continue;
    const TriangleSetup& s = setups[t];
    if (s.max_x < 0 || s.max_y < 0 || s.min_x >= buffer.width ||
        s.min_y >= buffer.height) {
      continue;
    }
    const int tx0 = std::max(0, s.min_x) / tile;
    const int ty0 = std::max(0, s.min_y) / tile;
    const int tx1 = std::min(buffer.width - 1, s.max_x) / tile;
    const int ty1 = std::min(buffer.height - 1, s.max_y) / tile;
    for (int ty = ty0; ty <= ty1; ++ty) {
      for (int tx = tx0; tx <= tx1; ++tx) bins[ty * tiles_x + tx].push_back(t);
    }
  }

  // Each tile owns its pixels: no two threads write the same pixel.
  ParallelFor(0, static_cast<int64_t>(bins.size()), [&](int64_t bin) {
    const int tx = static_cast<int>(bin % tiles_x);
    const int ty = static_cast<int>(bin / tiles_x);
    const int x0 = tx * tile;
    const int y0 = ty * tile;
    const int x1 = std::min(buffer.width, x0 + tile) - 1;
    const int y1 = std::min(buffer.height, y0 + tile) - 1;
    for (int32_t t : bins[bin]) {
      const TriangleSetup& s = setups[t];
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
        const int index = buffer.Index(px, py);
        if (depth < buffer.depth[index]) {
          buffer.depth[index] = depth;
          buffer.triangle[index] = t;
          buffer.bary[index] = b;
        }
      });
    }
  });
  return buffer;
}

}  // namespace hmc
