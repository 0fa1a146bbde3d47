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
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr float kInfF = std::numeric_limits<float>::infinity();

struct CellRange {
  std::array<int, 3> lo, hi;
};

// Per-thread visit marks so that a query tests each simplex once even when
// it is listed in several cells, without allocating per query.
struct VisitMarks {
  std::vector<uint32_t> marks;
  uint32_t epoch = 0;

  void Begin(size_t n) {
    if (marks.size() < n) marks.assign(n, 0);
    if (++epoch == 0) {
      std::fill(marks.begin(), marks.end(), 0);
      epoch = 1;
    }
  }
  bool Visit(uint32_t i) {
    if (marks[i] == epoch) return false;
    marks[i] = epoch;
    return true;
  }
};

// Per-thread closest points of the faces one query has computed, by face id
// (the same epoch scheme as VisitMarks).
struct FaceMemo {
  std::vector<uint32_t> epoch_of;
  std::vector<ClosestPoint> point;
  uint32_t epoch = 0;

  void Begin(size_t n) {
    if (epoch_of.size() < n) {
      epoch_of.assign(n, 0);
      point.resize(n);
    }
    if (++epoch == 0) {
      std::fill(epoch_of.begin(), epoch_of.end(), 0);
      epoch = 1;
    }
  }
};
thread_local FaceMemo face_memo;

// Per-thread open-addressing map from 64-bit keys (packed supports) to
// 32-bit values, emptied in O(1) per query by the same epoch scheme: a
// query inserts hundreds of supports, which std::unordered_map allocated
// and freed one node at a time.
struct KeyTable {
  std::vector<uint64_t> key;
  std::vector<uint32_t> value;
  std::vector<uint32_t> epoch_of;
  uint32_t epoch = 0;

  // Empties the table, with room for n keys at a load of at most 1/2.
  void Begin(size_t n) {
    size_t capacity = 64;
    while (capacity < 2 * n) capacity *= 2;
    if (capacity > key.size()) {
      key.assign(capacity, 0);
      value.assign(capacity, 0);
      epoch_of.assign(capacity, 0);
      epoch = 0;
    }
    if (++epoch == 0) {
      std::fill(epoch_of.begin(), epoch_of.end(), 0);
      epoch = 1;
    }
  }
  // The value stored under k, inserting v first if k is new (then true).
  std::pair<uint32_t*, bool> Insert(uint64_t k, uint32_t v) {
    // splitmix64's finaliser: packed ids differ in few bits.
    uint64_t h = k;
    h = (h ^ (h >> 30)) * 0xbf58476d1ce4e5b9ULL;
    h = (h ^ (h >> 27)) * 0x94d049bb133111ebULL;
    h ^= h >> 31;
    const size_t mask = key.size() - 1;
    for (size_t i = h & mask;; i = (i + 1) & mask) {
      if (epoch_of[i] != epoch) {
        epoch_of[i] = epoch;
        key[i] = k;
        value[i] = v;
        return {&value[i], true};
      }
      if (key[i] == k) return {&value[i], false};
    }
  }
};

// Inside test of a tetrahedron: convex barycentrics within tolerance, clamped
// and renormalised.
bool TetContains(const SimplexCorners& s, const Vec3& p, double tolerance,
                 std::array<double, 4>* weights) {
  if (!TetBarycentric(s.x[0], s.x[1], s.x[2], s.x[3], p, weights)) {
    return false;
  }
  if (*std::min_element(weights->begin(), weights->end()) < -tolerance) {
    return false;
  }
  double sum = 0;
  for (double& w : *weights) {
    w = std::max(w, 0.0);
    sum += w;
  }
  for (double& w : *weights) w /= sum;
  return true;
}

// Simplex s as a projection candidate with its closest point.
IndexCandidate Candidate(size_t s, const ClosestPoint& cp) {
  IndexCandidate cand;
  cand.simplex = static_cast<int>(s);
  cand.weights = cp.weights;
  cand.point = cp.point;
  cand.distance = cp.distance;
  return cand;
}

// Weights below `tolerance` become zero (the rest renormalised); returns
// the candidate's support (its corners of non-zero weight), packed.
// Candidates with the same support are the same point of the same face, so
// the same blend: a bundle on an edge of its cloud lies in every
// tetrahedron through that edge, and they must not all be scored.
uint64_t SnapAndKey(const CloudSimplex& s, double tolerance,
                    IndexCandidate* cand) {
  double sum = 0;
  for (int i = 0; i < s.size; ++i) {
    if (cand->weights[i] < tolerance) cand->weights[i] = 0.0;
    sum += cand->weights[i];
  }
  std::array<uint16_t, 4> support = {0xffff, 0xffff, 0xffff, 0xffff};
  int n = 0;
  for (int i = 0; i < s.size; ++i) {
    cand->weights[i] /= sum;
    if (cand->weights[i] > 0) support[n++] = s.corner[i];
  }
  // Sorted (unused slots, 0xffff, last) by a 4-element sorting network.
  auto order = [&](int i, int j) {
    if (support[j] < support[i]) std::swap(support[i], support[j]);
  };
  order(0, 1), order(2, 3), order(0, 2), order(1, 3), order(1, 2);
  uint64_t key = 0;
  for (uint16_t id : support) key = (key << 16) | id;
  return key;
}

// The candidates of `found` within `bound` of the query, in canonical form
// in *out: sorted by simplex id, snapped, one per support (the lowest id).
// A projection can keep hundreds (overlapping simplices share their closest
// face, edge or point): each support's lowest id is found in one pass, and
// only those are sorted.
void Canonicalize(const std::vector<CloudSimplex>& simplices,
                  double tolerance, double bound,
                  std::vector<IndexCandidate>* found,
                  std::vector<IndexCandidate>* out) {
  // support -> its slot in `order`, which holds the lowest id's index.
  thread_local KeyTable lowest;
  lowest.Begin(found->size());
  thread_local std::vector<uint32_t> order;
  order.clear();
  for (uint32_t i = 0; i < found->size(); ++i) {
    IndexCandidate& cand = (*found)[i];
    if (cand.distance > bound) continue;
    const auto [slot, inserted] = lowest.Insert(
        SnapAndKey(simplices[cand.simplex], tolerance, &cand),
        static_cast<uint32_t>(order.size()));
    if (inserted) {
      order.push_back(i);
    } else if (cand.simplex < (*found)[order[*slot]].simplex) {
      order[*slot] = i;
    }
  }
  std::sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) {
    return (*found)[a].simplex < (*found)[b].simplex;
  });
  out->clear();
  out->reserve(order.size());
  for (uint32_t i : order) out->push_back((*found)[i]);
}

}  // namespace

void BundleIndex::ComputeBoxes() {
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

double BundleIndex::OuterPlaneDistance(const Vec3& p) const {
  double out = -kInf;
  for (const Eigen::Vector4d& plane : outer_planes_) {
    out = std::max(out, plane.head<3>().dot(p) - plane[3]);
  }
  return out;
}

ClosestPoint BundleIndex::ClosestPointOutsideTet(int64_t s,
                                                 const Vec3& p) const {
  const SimplexCorners x = Corners(static_cast<int>(s));
  return NearestTetFace([&](int f) -> const ClosestPoint& {
    const uint32_t id = tet_faces_[s][f];
    if (face_memo.epoch_of[id] != face_memo.epoch) {
      face_memo.epoch_of[id] = face_memo.epoch;
      face_memo.point[id] =
          ClosestPointOnTriangle(x.x[kTetFaces[f][0]], x.x[kTetFaces[f][1]],
                                 x.x[kTetFaces[f][2]], p);
    }
    return face_memo.point[id];
  });
}

double BundleIndex::BoxDistance(int64_t s, const Vec3& p) const {
  const std::array<float, 6>& b = boxes_[s];
  double d2 = 0;
  for (int a = 0; a < 3; ++a) {
    const double out = std::max({double(b[a]) - p[a], p[a] - double(b[3 + a]), 0.0});
    d2 += out * out;
  }
  return std::sqrt(d2);
}

SimplexCorners BundleIndex::Corners(int simplex) const {
  const CloudSimplex& s = simplices_[simplex];
  SimplexCorners c;
  c.size = s.size;
  for (int i = 0; i < s.size; ++i) {
    c.x[i] = points_.row(s.corner[i]).transpose();
  }
  return c;
}

BundleIndex BundleIndex::Build(const MatX3d& points,
                               std::vector<int> point_shapes,
                               const IndexOptions& options) {
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

void BundleIndex::CollectInside(const uint32_t* begin, const uint32_t* end,
                                const Vec3& p, const IndexOptions& options,
                                std::vector<IndexCandidate>* out) const {
  // Ids ascend, so the first candidate of a support is the one Canonicalize
  // would keep, and the tetrahedra come before the lower-dimensional
  // simplices, which are skipped (all but the points) once a tetrahedron
  // holds p.
  thread_local KeyTable seen;
  seen.Begin(static_cast<size_t>(end - begin));
  const uint32_t first_point = static_cast<uint32_t>(simplices_.size() - NumPoints());
  for (const uint32_t* it = begin; it != end; ++it) {
    if (*it >= num_tets_ && *it < first_point && !out->empty()) {
      it = std::lower_bound(it, end, first_point);
      if (it == end) break;
    }
    IndexCandidate cand;
    if (!Contains(*it, p, options, &cand)) continue;
    if (seen.Insert(SnapAndKey(simplices_[*it], options.inside_tolerance, &cand), 0)
            .second) {
      out->push_back(cand);
    }
  }
}

IndexQuery BundleIndex::Query(const Vec3& p, double outside_slack_mm,
                              const IndexOptions& options) const {
  IndexQuery result;
  const std::array<int, 3> c = CellOf(p);
  const size_t cell = (static_cast<size_t>(c[2]) * grid_n_[1] + c[1]) * grid_n_[0] + c[0];
  // p = sum_i w_i x_i with every w_i >= -inside_tolerance (and sum 1) puts
  // p at most 3 inside_tolerance times the cloud's width beyond any plane
  // holding the cloud; a lower-dimensional simplex holds p within
  // on_data_mm of itself. Beyond both (and rounding), none can hold p, and
  // the inside test is skipped: most bundles that noise puts outside their
  // clouds are (90 % at 0.5 mm).
  const double reach = options.on_data_mm +
                       3.0 * options.inside_tolerance * diameter_ +
                       1e-12 * (1.0 + diameter_);
  if (OuterPlaneDistance(p) <= reach) {
    CollectInside(cell_items_.data() + cell_start_[cell],
                  cell_items_.data() + cell_start_[cell + 1], p, options,
                  &result.candidates);
  }
  if (!result.candidates.empty()) {
    result.inside = true;
    return result;
  }
  // Outside: grow shells of cells around p's (clamped) cell until no
  // unvisited simplex can come closer than the best plus the slack.
  thread_local VisitMarks marks;
  marks.Begin(simplices_.size());
  face_memo.Begin(num_faces_);
  double best = kInf;
  thread_local std::vector<IndexCandidate> found;
  found.clear();
  const double keep = outside_slack_mm + options.on_data_mm;
  auto visit = [&](uint32_t s) {
    if (!marks.Visit(s)) return;
    if (BoxDistance(s, p) > best + keep) return;
    // No tetrahedron holds p (CollectInside found none listed in p's cell,
    // or p is beyond the cloud's outer planes).
    const ClosestPoint cp =
        s < num_tets_ ? ClosestPointOutsideTet(s, p)
                      : ClosestPointOnSimplex(Corners(s), p,
                                              options.inside_tolerance);
    if (cp.distance > best + keep) return;
    best = std::min(best, cp.distance);
    found.push_back(Candidate(s, cp));
  };
  // The cells at Chebyshev distance r from p's.
  auto for_ring = [&](int r, auto&& f) {
    for (int z = std::max(c[2] - r, 0); z <= std::min(c[2] + r, grid_n_[2] - 1); ++z) {
      for (int y = std::max(c[1] - r, 0); y <= std::min(c[1] + r, grid_n_[1] - 1); ++y) {
        for (int x = std::max(c[0] - r, 0); x <= std::min(c[0] + r, grid_n_[0] - 1); ++x) {
          if (std::max({std::abs(x - c[0]), std::abs(y - c[1]),
                        std::abs(z - c[2])}) == r) {
            f((static_cast<size_t>(z) * grid_n_[1] + y) * grid_n_[0] + x);
          }
        }
      }
    }
  };
  const uint32_t num_simplices = static_cast<uint32_t>(simplices_.size());
  for (int r = 0;; ++r) {
    // Overlapping simplices are listed in many cells: once a ring lists
    // more entries than the index has simplices (typically from r = 1 on,
    // ~6000 entries against ~2000 simplices), one pass over all of them is
    // cheaper, and ends the search.
    size_t listed = 0;
    for_ring(r, [&](size_t id) { listed += cell_start_[id + 1] - cell_start_[id]; });
    if (r > 0 && listed >= num_simplices) {
      for (uint32_t s = 0; s < num_simplices; ++s) visit(s);
      break;
    }
    for_ring(r, [&](size_t id) {
      for (uint32_t k = cell_start_[id]; k < cell_start_[id + 1]; ++k) {
        visit(cell_items_[k]);
      }
    });
    double bound = kInf;
    for (int a = 0; a < 3; ++a) {
      if (c[a] - r > 0) {
        bound = std::min(bound, p[a] - (grid_origin_[a] + (c[a] - r) * cell_size_));
      }
      if (c[a] + r < grid_n_[a] - 1) {
        bound = std::min(
            bound, grid_origin_[a] + (c[a] + r + 1) * cell_size_ - p[a]);
      }
    }
    if (bound == kInf || best + keep < bound) break;
  }
  Canonicalize(simplices_, options.inside_tolerance, best + keep, &found,
               &result.candidates);
  result.inside = best <= options.on_data_mm;
  result.distance = result.inside ? 0.0 : best;
  return result;
}

bool BundleIndex::Contains(int64_t s, const Vec3& p,
                           const IndexOptions& options,
                           IndexCandidate* candidate) const {
  if (BoxDistance(s, p) > options.on_data_mm) return false;
  if (s < num_tets_) {
    if (!TetContains(Corners(s), p, options.inside_tolerance,
                     &candidate->weights)) {
      return false;
    }
  } else {
    const SimplexCorners corners = Corners(s);
    if (corners.size == 3) {
      // Off the triangle's plane: no closest-point search needed.
      const Vec3 n = (corners.x[1] - corners.x[0]).cross(corners.x[2] - corners.x[0]);
      if (std::abs(n.dot(p - corners.x[0])) > options.on_data_mm * n.norm()) {
        return false;
      }
    }
    const ClosestPoint cp =
        ClosestPointOnSimplex(corners, p, options.inside_tolerance);
    if (cp.distance > options.on_data_mm) return false;
    candidate->weights = cp.weights;
  }
  candidate->simplex = static_cast<int>(s);
  candidate->point = p;
  return true;
}

IndexQuery BundleIndex::QueryBruteForce(const Vec3& p, double outside_slack_mm,
                                        const IndexOptions& options) const {
  IndexQuery result;
  std::vector<uint32_t> all_ids(simplices_.size());
  std::iota(all_ids.begin(), all_ids.end(), 0u);
  CollectInside(all_ids.data(), all_ids.data() + all_ids.size(), p, options,
                &result.candidates);
  if (!result.candidates.empty()) {
    result.inside = true;
    return result;
  }
  std::vector<IndexCandidate> all;
  double best = kInf;
  for (size_t s = 0; s < simplices_.size(); ++s) {
    const ClosestPoint cp = ClosestPointOnSimplex(
        Corners(static_cast<int>(s)), p, options.inside_tolerance);
    all.push_back(Candidate(s, cp));
    best = std::min(best, cp.distance);
  }
  const double keep = outside_slack_mm + options.on_data_mm;
  Canonicalize(simplices_, options.inside_tolerance, best + keep, &all,
               &result.candidates);
  result.inside = best <= options.on_data_mm;
  result.distance = result.inside ? 0.0 : best;
  return result;
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
