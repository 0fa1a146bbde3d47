// Method step 3 (docs/ARCHITECTURE.md): the uniform grid listing the
// simplices overlapping each cell (indexing/bundle_index.h).
#include <algorithm>
#include <array>
#include <cmath>
#include <tuple>
#include <utility>
#include <vector>

#include "core/mesh.h"
#include "indexing/bundle_index.h"

namespace hmc {
namespace {

struct CellRange {
  std::array<int, 3> lo, hi;
};

}  // namespace

void BundleIndex::BuildGrid(const IndexOptions& options) {
  const Eigen::Matrix<double, 2, 3> box = BoundingBox(points_);
  const Vec3 extent = (box.row(1) - box.row(0)).transpose();
  const double pad = std::max(options.on_data_mm, 1e-9 * extent.maxCoeff());
  const Vec3 lo = box.row(0).transpose() - Vec3::Constant(pad);
  const Vec3 size = extent + Vec3::Constant(2 * pad);
  grid_origin_ = lo;

  const size_t S = simplices_.size();
  // The simplices' boxes (ComputeBoxes, rounded outwards), padded.
  std::vector<Eigen::Matrix<double, 2, 3>> boxes(S);
  for (size_t i = 0; i < S; ++i) {
    for (int a = 0; a < 3; ++a) {
      boxes[i](0, a) = boxes_[i][a] - pad;
      boxes[i](1, a) = boxes_[i][3 + a] + pad;
    }
  }
  auto range_of = [&](const Eigen::Matrix<double, 2, 3>& b, double h,
                      const std::array<int, 3>& n) {
    CellRange r;
    for (int a = 0; a < 3; ++a) {
      r.lo[a] = std::clamp(
          static_cast<int>(std::floor((b(0, a) - grid_origin_[a]) / h)), 0,
          n[a] - 1);
      r.hi[a] = std::clamp(
          static_cast<int>(std::floor((b(1, a) - grid_origin_[a]) / h)), 0,
          n[a] - 1);
    }
    return r;
  };
  const double budget =
      options.grid_entries_per_element * static_cast<double>(S);
  auto layout = [&](int n_max) {
    const double h = size.maxCoeff() / n_max;
    std::array<int, 3> n;
    for (int a = 0; a < 3; ++a) {
      n[a] = std::clamp(static_cast<int>(std::ceil(size[a] / h)), 1, n_max);
    }
    return std::make_pair(h, n);
  };
  auto entries_of = [&](int n_max) {
    const auto [h, n] = layout(n_max);
    double entries = 0;
    for (size_t i = 0; i < S; ++i) {
      const CellRange r = range_of(boxes[i], h, n);
      entries += double(r.hi[0] - r.lo[0] + 1) * (r.hi[1] - r.lo[1] + 1) *
                 (r.hi[2] - r.lo[2] + 1);
    }
    return entries;
  };
  // The finest grid within the memory budget (entries grow with the
  // resolution; bisection over the cells along the longest side).
  int fine = options.grid_max_cells, coarse = 1;
  if (entries_of(fine) <= budget) {
    coarse = fine;
  } else {
    while (fine - coarse > 1) {
      const int mid = (coarse + fine) / 2;
      (entries_of(mid) <= budget ? coarse : fine) = mid;
    }
  }
  std::tie(cell_size_, grid_n_) = layout(coarse);
  const size_t cells = static_cast<size_t>(grid_n_[0]) * grid_n_[1] * grid_n_[2];
  cell_start_.assign(cells + 1, 0);
  auto cell_id = [&](int x, int y, int z) {
    return (static_cast<size_t>(z) * grid_n_[1] + y) * grid_n_[0] + x;
  };
  for (int pass = 0; pass < 2; ++pass) {
    std::vector<uint32_t> fill;
    if (pass == 1) {
      for (size_t c = 0; c < cells; ++c) cell_start_[c + 1] += cell_start_[c];
      cell_items_.assign(cell_start_[cells], 0);
      fill.assign(cell_start_.begin(), cell_start_.end() - 1);
    }
    for (size_t i = 0; i < S; ++i) {
      const CellRange r = range_of(boxes[i], cell_size_, grid_n_);
      for (int z = r.lo[2]; z <= r.hi[2]; ++z) {
        for (int y = r.lo[1]; y <= r.hi[1]; ++y) {
          for (int xx = r.lo[0]; xx <= r.hi[0]; ++xx) {
            const size_t c = cell_id(xx, y, z);
            if (pass == 0) {
              ++cell_start_[c + 1];
            } else {
              cell_items_[fill[c]++] = static_cast<uint32_t>(i);
            }
          }
        }
      }
    }
  }
  stats_.grid_cells = grid_n_;
  stats_.grid_entries = static_cast<int64_t>(cell_items_.size());
  stats_.memory_bytes = static_cast<int64_t>(
      points_.size() * sizeof(double) + point_shapes_.size() * sizeof(int) +
      simplices_.size() * (sizeof(CloudSimplex) + sizeof(boxes_[0])) +
      tet_faces_.size() * sizeof(tet_faces_[0]) +
      outer_planes_.size() * sizeof(outer_planes_[0]) +
      cell_start_.size() * sizeof(uint32_t) +
      cell_items_.size() * sizeof(uint32_t));
}

std::array<int, 3> BundleIndex::CellOf(const Vec3& p) const {
  std::array<int, 3> c;
  for (int a = 0; a < 3; ++a) {
    const double f = std::floor((p[a] - grid_origin_[a]) / cell_size_);
    c[a] = static_cast<int>(
        std::clamp(std::isfinite(f) ? f : 0.0, 0.0, double(grid_n_[a] - 1)));
  }
  return c;
}

}  // namespace hmc
