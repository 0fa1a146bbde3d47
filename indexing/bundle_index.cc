// Method steps 1-2 (docs/ARCHITECTURE.md): the bundle's cloud and its
// simplices, with what the query needs of them (boxes, face ids, outer
// planes), and the index's binary form. The grid is in
// bundle_index_grid.cc, the query in bundle_index_query.cc.
#include "indexing/bundle_index.h"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <limits>
#include <numeric>
#include <tuple>
#include <unordered_map>
#include <utility>

#include "core/error.h"
#include "core/mesh.h"
#include "indexing/binary_io.h"

namespace hmc {

void BundleIndex::ComputeBoxes() {
  constexpr float kInfF = std::numeric_limits<float>::infinity();
  boxes_.resize(simplices_.size());
  for (size_t i = 0; i < simplices_.size(); ++i) {
    const CloudSimplex& s = simplices_[i];
    for (int a = 0; a < 3; ++a) {
      double lo = points_(s.corner[0], a), hi = lo;
      for (int k = 1; k < s.size; ++k) {
        lo = std::min(lo, points_(s.corner[k], a));
        hi = std::max(hi, points_(s.corner[k], a));
      }
      // Rounded outwards, so the float box holds the double one.
      boxes_[i][a] = std::nextafter(static_cast<float>(lo), -kInfF);
      boxes_[i][3 + a] = std::nextafter(static_cast<float>(hi), kInfF);
    }
  }
}

void BundleIndex::ComputeFaces() {
  tet_faces_.resize(num_tets_);
  std::unordered_map<uint64_t, uint32_t> id_of;
  for (int64_t t = 0; t < num_tets_; ++t) {
    const CloudSimplex& s = simplices_[t];
    for (int f = 0; f < 4; ++f) {
      uint64_t key = 0;
      for (int i : kTetFaces[f]) key = (key << 16) | s.corner[i];
      tet_faces_[t][f] =
          id_of.emplace(key, static_cast<uint32_t>(id_of.size())).first->second;
    }
  }
  num_faces_ = static_cast<uint32_t>(id_of.size());
}

void BundleIndex::ComputeOuterPlanes() {
  // 64 directions spread over the sphere (a Fibonacci lattice).
  constexpr int kDirections = 64;
  const double golden = M_PI * (3.0 - std::sqrt(5.0));
  outer_planes_.resize(kDirections);
  for (int i = 0; i < kDirections; ++i) {
    const double z = 1.0 - (2.0 * i + 1.0) / kDirections;
    const double r = std::sqrt(1.0 - z * z);
    const Vec3 n(r * std::cos(golden * i), r * std::sin(golden * i), z);
    const double offset = (points_ * n).maxCoeff();
    outer_planes_[i] << n, offset;
  }
  const Eigen::Matrix<double, 2, 3> box = BoundingBox(points_);
  diameter_ = (box.row(1) - box.row(0)).norm();
}

BundleIndex BundleIndex::Build(const MatX3d& points,
                               std::vector<int> point_shapes,
                               const IndexOptions& options) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  const int P = static_cast<int>(points.rows());
  HMC_CHECK(P >= 1 && P < 65535);
  HMC_CHECK(static_cast<int>(point_shapes.size()) == P);
  BundleIndex index;
  index.points_ = points;
  index.point_shapes_ = std::move(point_shapes);

  Eigen::MatrixXd d2(P, P);
  for (int i = 0; i < P; ++i) {
    for (int j = 0; j < P; ++j) {
      d2(i, j) = (points.row(i) - points.row(j)).squaredNorm();
    }
  }
  const double max_edge2 =
      options.max_edge_mm > 0 ? options.max_edge_mm * options.max_edge_mm
                              : kInf;
  auto x = [&](int i) -> Vec3 { return points.row(i).transpose(); };
  // The radius graph: up[i] = the points j > i within the edge bound,
  // ascending. A kept simplex is a clique of it, so the simplices are
  // enumerated as cliques (i < j < k < l, in lexicographic order) from the
  // common neighbours of their first two corners, and the work grows with
  // the simplices within the bound rather than with C(P, 4).
  // With max_edge_neighbours = k, an edge also needs one of its points
  // among the other's k nearest (the union of the k-nearest-neighbour
  // graphs): near2[i] = squared distance to i's k-th nearest point.
  std::vector<double> near2(P, kInf);
  const int k_near = options.max_edge_neighbours;
  if (k_near > 0 && k_near < P - 1) {
    std::vector<double> row(P);
    for (int i = 0; i < P; ++i) {
      for (int j = 0; j < P; ++j) row[j] = d2(i, j);
      // row[i] = 0 is the smallest: the k-th nearest other point is at k.
      std::nth_element(row.begin(), row.begin() + k_near, row.end());
      near2[i] = row[k_near];
    }
  }
  auto joined = [&](int i, int j) {
    return d2(i, j) <= max_edge2 && (d2(i, j) <= near2[i] || d2(i, j) <= near2[j]);
  };
  std::vector<std::vector<uint16_t>> up(P);
  for (int i = 0; i < P; ++i) {
    for (int j = i + 1; j < P; ++j) {
      if (joined(i, j)) up[i].push_back(static_cast<uint16_t>(j));
    }
  }
  std::vector<uint16_t> common;  // up[i] ∩ up[j]: the k that close (i, j)
  auto intersect = [&](int i, int j) {
    common.clear();
    std::set_intersection(up[i].begin(), up[i].end(), up[j].begin(), up[j].end(),
                          std::back_inserter(common));
  };
  // The triangles that are faces of kept tetrahedra (sorted keys): only the
  // others are kept, so they add coverage without duplicating.
  auto tri_key = [P](int i, int j, int k) {
    return (static_cast<uint64_t>(i) * P + j) * P + k;
  };
  std::vector<uint64_t> covered_triangle;
  for (int i = 0; i < P; ++i) {
    for (const int j : up[i]) {
      intersect(i, j);
      for (size_t a = 0; a < common.size(); ++a) {
        const int k = common[a];
        for (size_t b = a + 1; b < common.size(); ++b) {
          const int l = common[b];
          if (!joined(k, l)) continue;
          const double q = TetQuality(x(i), x(j), x(k), x(l));
          if (q < options.min_tet_quality || q == 0.0) continue;
          CloudSimplex s;
          s.corner = {static_cast<uint16_t>(i), static_cast<uint16_t>(j),
                      static_cast<uint16_t>(k), static_cast<uint16_t>(l)};
          s.size = 4;
          index.simplices_.push_back(s);
          covered_triangle.insert(covered_triangle.end(),
                                  {tri_key(i, j, k), tri_key(i, j, l),
                                   tri_key(i, k, l), tri_key(j, k, l)});
        }
      }
    }
  }
  std::sort(covered_triangle.begin(), covered_triangle.end());
  covered_triangle.erase(std::unique(covered_triangle.begin(), covered_triangle.end()),
                         covered_triangle.end());
  index.num_tets_ = static_cast<int64_t>(index.simplices_.size());
  // Which edges are sides of kept triangles or tetrahedra.
  std::vector<uint8_t> covered_edge(static_cast<size_t>(P) * P, 0);
  auto edge_key = [P](int i, int j) { return static_cast<size_t>(i) * P + j; };
  int64_t triangles = 0, edges = 0;
  for (int i = 0; i < P; ++i) {
    for (const int j : up[i]) {
      intersect(i, j);
      for (const int k : common) {
        const bool covered = std::binary_search(
            covered_triangle.begin(), covered_triangle.end(), tri_key(i, j, k));
        if (!covered) {
          const double q = TriangleQuality(x(i), x(j), x(k));
          if (q < options.min_triangle_quality || q == 0.0) continue;
          CloudSimplex s;
          s.corner = {static_cast<uint16_t>(i), static_cast<uint16_t>(j),
                      static_cast<uint16_t>(k), 0};
          s.size = 3;
          index.simplices_.push_back(s);
          ++triangles;
        }
        covered_edge[edge_key(i, j)] = covered_edge[edge_key(i, k)] =
            covered_edge[edge_key(j, k)] = 1;
      }
    }
  }
  for (int i = 0; i < P; ++i) {
    for (const int j : up[i]) {
      if (covered_edge[edge_key(i, j)] || d2(i, j) == 0.0) continue;
      CloudSimplex s;
      s.corner = {static_cast<uint16_t>(i), static_cast<uint16_t>(j), 0, 0};
      s.size = 2;
      index.simplices_.push_back(s);
      ++edges;
    }
  }
  // Every point is also a simplex of its own (the last P simplices), so a
  // solve can snap to a point (see PointSimplex).
  for (int i = 0; i < P; ++i) {
    CloudSimplex s;
    s.corner = {static_cast<uint16_t>(i), 0, 0, 0};
    s.size = 1;
    index.simplices_.push_back(s);
  }

  BundleIndexStats& st = index.stats_;
  st.points = P;
  st.tets_candidate = static_cast<int64_t>(P) * (P - 1) * (P - 2) * (P - 3) / 24;
  st.tets_kept = index.num_tets_;
  st.triangles_kept = triangles;
  st.edges_kept = edges;
  index.ComputeBoxes();
  index.ComputeFaces();
  index.ComputeOuterPlanes();
  index.BuildGrid(options);
  return index;
}

void BundleIndex::Write(std::ostream& out) const {
  WritePod<int32_t>(out, NumPoints());
  out.write(reinterpret_cast<const char*>(points_.data()),
            static_cast<std::streamsize>(points_.size() * sizeof(double)));
  WritePodVector(out, point_shapes_);
  // Field by field: CloudSimplex has a padding byte (docs/formats.md).
  WritePod<uint64_t>(out, simplices_.size());
  for (const CloudSimplex& s : simplices_) {
    for (const uint16_t corner : s.corner) WritePod(out, corner);
    WritePod(out, s.size);
  }
  WritePod(out, num_tets_);
  for (int axis = 0; axis < 3; ++axis) WritePod(out, grid_origin_[axis]);
  WritePod(out, cell_size_);
  WritePod(out, grid_n_);
  WritePodVector(out, cell_start_);
  WritePodVector(out, cell_items_);
  WritePod(out, stats_.points);
  WritePod(out, stats_.tets_candidate);
  WritePod(out, stats_.tets_kept);
  WritePod(out, stats_.triangles_kept);
  WritePod(out, stats_.edges_kept);
  WritePod(out, stats_.grid_cells);
  WritePod(out, stats_.grid_entries);
  WritePod(out, stats_.memory_bytes);
}

BundleIndex BundleIndex::Read(std::istream& in) {
  BundleIndex index;
  const int32_t P = ReadPod<int32_t>(in);
  if (P < 1 || P >= 65535) throw InputError("index cache: bad point count");
  index.points_.resize(P, 3);
  in.read(reinterpret_cast<char*>(index.points_.data()),
          static_cast<std::streamsize>(index.points_.size() * sizeof(double)));
  if (!in) throw InputError("index cache: unexpected end of file");
  index.point_shapes_ = ReadPodVector<int>(in);
  {
    const uint64_t n = ReadPod<uint64_t>(in);
    // 9 bytes a simplex; no more than the 16 GiB ReadPodVector allows.
    if (n > (1ull << 34) / 9) throw InputError("index cache: implausible array size");
    // Grown as read, so a lying count fails at the end of the file rather
    // than allocating it first.
    for (uint64_t i = 0; i < n; ++i) {
      CloudSimplex s;
      for (uint16_t& corner : s.corner) corner = ReadPod<uint16_t>(in);
      s.size = ReadPod<uint8_t>(in);
      index.simplices_.push_back(s);
    }
  }
  index.num_tets_ = ReadPod<int64_t>(in);
  for (int axis = 0; axis < 3; ++axis) index.grid_origin_[axis] = ReadPod<double>(in);
  index.cell_size_ = ReadPod<double>(in);
  index.grid_n_ = ReadPod<std::array<int, 3>>(in);
  index.cell_start_ = ReadPodVector<uint32_t>(in);
  index.cell_items_ = ReadPodVector<uint32_t>(in);
  index.stats_.points = ReadPod<int>(in);
  index.stats_.tets_candidate = ReadPod<int64_t>(in);
  index.stats_.tets_kept = ReadPod<int64_t>(in);
  index.stats_.triangles_kept = ReadPod<int64_t>(in);
  index.stats_.edges_kept = ReadPod<int64_t>(in);
  index.stats_.grid_cells = ReadPod<std::array<int, 3>>(in);
  index.stats_.grid_entries = ReadPod<int64_t>(in);
  index.stats_.memory_bytes = ReadPod<int64_t>(in);
  // Validate what the queries index with, so a corrupt cache cannot read out
  // of bounds.
  const size_t cells =
      static_cast<size_t>(index.grid_n_[0]) * index.grid_n_[1] * index.grid_n_[2];
  bool ok = static_cast<int>(index.point_shapes_.size()) == P &&
            index.num_tets_ >= 0 &&
            index.num_tets_ <= static_cast<int64_t>(index.simplices_.size()) &&
            index.grid_n_[0] >= 1 && index.grid_n_[1] >= 1 &&
            index.grid_n_[2] >= 1 && index.cell_start_.size() == cells + 1 &&
            index.cell_start_.back() == index.cell_items_.size() &&
            index.cell_size_ > 0;
  for (const auto& s : index.simplices_) {
    ok = ok && s.size >= 1 && s.size <= 4;
    for (int i = 0; ok && i < s.size; ++i) ok = s.corner[i] < P;
  }
  for (size_t c = 0; ok && c < cells; ++c) {
    ok = index.cell_start_[c] <= index.cell_start_[c + 1];
  }
  for (uint32_t item : index.cell_items_) {
    ok = ok && item < index.simplices_.size();
  }
  ok = ok && index.simplices_.size() >= static_cast<size_t>(P);
  for (int i = 0; ok && i < P; ++i) {
    const CloudSimplex& s = index.simplices_[index.simplices_.size() - P + i];
    ok = s.size == 1 && s.corner[0] == i;
  }
  if (!ok) throw InputError("index cache: inconsistent bundle index");
  index.ComputeBoxes();
  index.ComputeFaces();
  index.ComputeOuterPlanes();
  return index;
}

}  // namespace hmc
