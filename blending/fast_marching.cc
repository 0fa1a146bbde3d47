#include "blending/fast_marching.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <queue>
#include <utility>

#include "core/error.h"

namespace hmc {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr char kTrial = 0;
constexpr char kAccepted = 1;
constexpr char kRejected = 2;

using HeapEntry = std::pair<double, int>;
using MinHeap = std::priority_queue<HeapEntry, std::vector<HeapEntry>,
                                    std::greater<HeapEntry>>;

}  // namespace

FastMarching::FastMarching(const MatX3d& V, const MatX3i& F) : V_(V), F_(F) {
  const int num_vertices = static_cast<int>(V.rows());
  tri_start_.assign(num_vertices + 1, 0);
  for (int f = 0; f < F.rows(); ++f) {
    for (int i = 0; i < 3; ++i) {
      HMC_CHECK(F(f, i) >= 0 && F(f, i) < num_vertices);
      ++tri_start_[F(f, i) + 1];
    }
  }
  for (int v = 0; v < num_vertices; ++v) tri_start_[v + 1] += tri_start_[v];
  tri_.resize(tri_start_[num_vertices]);
  std::vector<int> fill(tri_start_.begin(), tri_start_.end() - 1);
  for (int f = 0; f < F.rows(); ++f) {
    for (int i = 0; i < 3; ++i) tri_[fill[F(f, i)]++] = f;
  }
}

double FastMarching::TriangleUpdate(int v, int a, double ta, int b,
                                    double tb) const {
  const Vec3 e1 = V_.row(a) - V_.row(v);
  const Vec3 e2 = V_.row(b) - V_.row(v);
  const double edge_update =
      std::min(ta + e1.norm(), tb + e2.norm());  // Dijkstra fallback
  // Planar wavefront T(v + x) = t + n.x with |n| = 1 through (a, ta) and
  // (b, tb): with E = [e1 e2]^T, G = E E^T, Q = G^-1, u = (ta, tb),
  // n = E^T Q (u - t 1) and |n| = 1 gives
  // t^2 (1'Q1) - 2 t (1'Qu) + (u'Qu - 1) = 0.
  const double g11 = e1.squaredNorm(), g22 = e2.squaredNorm(),
               g12 = e1.dot(e2);
  const double det = g11 * g22 - g12 * g12;
  if (!(det > 1e-12 * g11 * g22)) return edge_update;  // degenerate triangle
  const double q11 = g22 / det, q22 = g11 / det, q12 = -g12 / det;
  const double qa = q11 + q12, qb = q12 + q22;  // Q 1
  const double A = qa + qb;
  const double B = qa * ta + qb * tb;
  const double C = q11 * ta * ta + 2 * q12 * ta * tb + q22 * tb * tb - 1.0;
  const double disc = B * B - A * C;
  if (disc < 0 || A <= 0) return edge_update;
  const double t = (B + std::sqrt(disc)) / A;
  // Upwind condition: the characteristic -n = E^T Q (t 1 - u) must come
  // from inside the triangle, i.e. both coefficients non-negative.
  const double c1 = q11 * (t - ta) + q12 * (t - tb);
  const double c2 = q12 * (t - ta) + q22 * (t - tb);
  if (c1 < 0 || c2 < 0 || t < std::max(ta, tb)) return edge_update;
  return std::min(t, edge_update);
}

namespace {

// The march shared by Run and MarchBounded. `labels` may be null.
template <typename Bound>
void March(const FastMarching& fm, const MatX3d& V, const MatX3i& F,
           const std::vector<MarchSource>& sources, const Bound& bound,
           FastMarching::Scratch* s, std::vector<int>* labels) {
  const int num_vertices = fm.NumVertices();
  if (static_cast<int>(s->stamp.size()) != num_vertices) {
    s->distance.assign(num_vertices, kInf);
    s->stamp.assign(num_vertices, 0);
    s->state.assign(num_vertices, kTrial);
    s->generation = 0;
  }
  ++s->generation;
  const int gen = s->generation;
  s->accepted.clear();
  auto touch = [&](int v) {
    if (s->stamp[v] != gen) {
      s->stamp[v] = gen;
      s->distance[v] = kInf;
      s->state[v] = kTrial;
    }
  };
  MinHeap heap;
  for (const MarchSource& source : sources) {
    HMC_CHECK(source.vertex >= 0 && source.vertex < num_vertices);
    touch(source.vertex);
    if (source.distance < s->distance[source.vertex]) {
      s->distance[source.vertex] = source.distance;
      if (labels) (*labels)[source.vertex] = source.label;
      heap.emplace(source.distance, source.vertex);
    }
  }
  const std::vector<int>& tri_start = fm.tri_start();
  const std::vector<int>& tri = fm.tri();
  while (!heap.empty()) {
    const auto [d, v] = heap.top();
    heap.pop();
    if (s->state[v] != kTrial || d > s->distance[v]) continue;  // stale
    if (!(d < bound(v))) {
      s->state[v] = kRejected;  // final, but outside the region: no spread
      continue;
    }
    s->state[v] = kAccepted;
    s->accepted.push_back(v);
    for (int k = tri_start[v]; k < tri_start[v + 1]; ++k) {
      const int f = tri[k];
      int others[2];
      int n = 0;
      for (int i = 0; i < 3; ++i) {
        if (F(f, i) != v) others[n++] = F(f, i);
      }
      if (n != 2) continue;  // degenerate triangle listing v twice
      for (int j = 0; j < 2; ++j) {
        const int w = others[j], x = others[1 - j];
        touch(w);
        if (s->state[w] != kTrial) continue;
        touch(x);
        double candidate = d + (V.row(w) - V.row(v)).norm();
        // Only a triangle whose known corners belong to the same source
        // carries one planar wavefront; across a Voronoi border the planar
        // fit through two fronts would underestimate.
        if (s->state[x] != kTrial && (!labels || (*labels)[x] == (*labels)[v])) {
          candidate = std::min(
              candidate, fm.TriangleUpdate(w, v, d, x, s->distance[x]));
        }
        if (candidate < s->distance[w]) {
          s->distance[w] = candidate;
          if (labels) (*labels)[w] = (*labels)[v];
          heap.emplace(candidate, w);
        }
      }
    }
  }
}

}  // namespace

FastMarching::Result FastMarching::Run(
    const std::vector<MarchSource>& sources) const {
  Scratch scratch;
  std::vector<int> labels(NumVertices(), -1);
  March(*this, V_, F_, sources, [](int) { return kInf; }, &scratch, &labels);
  Result result;
  result.distance.resize(NumVertices());
  result.label.resize(NumVertices());
  for (int v = 0; v < NumVertices(); ++v) {
    const bool reached = scratch.stamp[v] == scratch.generation &&
                         scratch.state[v] == kAccepted;
    result.distance[v] = reached ? scratch.distance[v] : kInf;
    result.label[v] = reached ? labels[v] : -1;
  }
  return result;
}

void FastMarching::MarchBounded(int source, const Eigen::VectorXd& bound,
                                Scratch* scratch) const {
  HMC_CHECK(bound.size() == NumVertices());
  March(*this, V_, F_, {MarchSource{source, 0.0, 0}},
        [&bound](int v) { return bound[v]; }, scratch, nullptr);
}

}  // namespace hmc
