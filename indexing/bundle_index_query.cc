// Method steps 4-5 (docs/ARCHITECTURE.md): the simplices holding a bundle,
// with their barycentric weights, or the closest ones when none does
// (indexing/bundle_index.h, Query).
#include <algorithm>
#include <cmath>
#include <iterator>
#include <limits>
#include <numeric>
#include <utility>
#include <vector>

#include "core/error.h"
#include "indexing/bundle_index.h"

namespace hmc {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

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

}  // namespace hmc
