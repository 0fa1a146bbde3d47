#include "blending/lgi_solver.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

#include <fmt/format.h>

#include "core/error.h"
#include "core/logging.h"
#include "core/parallel.h"

namespace hmc {

void SolveOptions::Register(OptionFields* fields) {
  fields->SetGroup("solve");
  fields->Add("outside_slack_mm", &outside_slack_mm,
              "outside the data, simplices this close to the closest one "
              "compete by the neighbour criterion (mm)")
      .AtLeast(0);
  fields->Add("temporal_preference", &temporal_preference,
              "candidates within this fraction of the best neighbour cost "
              "compete by shapes shared with the previous frame (0 = off)")
      .AtLeast(0);
  fields->Add("tie_mm2", &tie_mm2,
              "candidates whose neighbour costs differ by at most this are "
              "tied; ties go to agreement with the neighbours' choices, then "
              "to the least motion (mm^2)")
      .AtLeast(0);
  fields->Add("smooth_window", &smooth_window,
              "frames of the centred moving average of shape weights "
              "(0 = off)")
      .AtLeast(0);
  fields->Add("min_bundle_fraction", &min_bundle_fraction,
              "frames with fewer observed bundles (fraction of markers) are "
              "flagged bad and skipped (every method)")
      .In(0, 1);
  fields->SetGroup("");
}

bool SolveOptions::Check() const {
  CHECK_OPTION_LIMITS();
  return true;
}

LgiSolver::LgiSolver(const TriMesh& neutral, const ShapeData& data,
                     const ShapeIndex& index,
                     const NaturalNeighbourWeights& nn,
                     const IndexOptions& index_options,
                     const SolveOptions& options)
    : neutral_(neutral),
      data_(data),
      index_(index),
      nn_(nn),
      index_options_(index_options),
      options_(options) {
  HMC_CHECK(neutral.NumVertices() == data.num_vertices);
  HMC_CHECK(static_cast<int>(index.bundles.size()) == data.num_bundles);
  HMC_CHECK(static_cast<int>(index.represented.size()) == data.num_bundles);
  HMC_CHECK(nn.weights.rows() == data.num_vertices);
  HMC_CHECK(nn.weights.cols() == data.num_bundles);
  HMC_CHECK(static_cast<int>(nn.site_neighbours.size()) == data.num_bundles);
  const int K = data.num_bundles;
  for (int k = 0; k < K; ++k) marker_index_[data.bundle_names[k]] = k;
  neighbours_.resize(K);
  site_disp_.resize(K);
  gram_.resize(K);
  alt_point_.resize(K);
  alt_shape_.resize(K);
  alt_disp_.resize(K);
  alt_site_.resize(K);
  ParallelFor(0, K, [&](int64_t k) {
    for (int j : nn.site_neighbours[k]) {
      if (j != k) neighbours_[k].push_back(j);
    }
    const BundleIndex& b = index.bundles[k];
    const int P = b.NumPoints();
    const int J = static_cast<int>(neighbours_[k].size());
    Eigen::MatrixXd d = Eigen::MatrixXd::Zero(P, 3 * J);
    for (int i = 0; i < P; ++i) {
      const int shape = b.point_shapes()[i];
      if (shape < 0) continue;
      for (int jj = 0; jj < J; ++jj) {
        d.block<1, 3>(i, 3 * jj) =
            data.SiteDisplacement(shape, neighbours_[k][jj]).transpose();
      }
    }
    gram_[k] = d * d.transpose();
    site_disp_[k] = std::move(d);
    for (int i = 0; i < P; ++i) {
      for (int r : index.represented[k][i]) {
        if (r == b.point_shapes()[i]) continue;
        alt_point_[k].push_back(i);
        alt_shape_[k].push_back(r);
      }
    }
    const int A = static_cast<int>(alt_point_[k].size());
    alt_disp_[k] = Eigen::MatrixXd::Zero(A, 3 * J);
    alt_site_[k].assign(A, data.site_neutral.row(k).transpose());
    for (int a = 0; a < A; ++a) {
      const int r = alt_shape_[k][a];
      if (r < 0) continue;
      alt_site_[k][a] += data.SiteDisplacement(r, static_cast<int>(k));
      for (int jj = 0; jj < J; ++jj) {
        alt_disp_[k].block<1, 3>(a, 3 * jj) =
            data.SiteDisplacement(r, neighbours_[k][jj]).transpose();
      }
    }
  });
  std::vector<std::vector<std::pair<int, double>>> region(K);
  for (int v = 0; v < nn.weights.rows(); ++v) {
    for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(
             nn.weights, v);
         it; ++it) {
      if (it.value() > 0) region[it.col()].emplace_back(v, it.value());
    }
  }
  point_motion_.resize(K);
  ParallelFor(0, K, [&](int64_t k) {
    const BundleIndex& b = index.bundles[k];
    point_motion_[k].assign(b.NumPoints(), 0.0);
    for (int i = 0; i < b.NumPoints(); ++i) {
      const int shape = b.point_shapes()[i];
      if (shape < 0) continue;
      double motion = 0;
      for (const auto& [v, lambda] : region[k]) {
        const float* d = data.Displacement(v, shape);
        if (!d) continue;
        motion += lambda * std::sqrt(double(d[0]) * d[0] + double(d[1]) * d[1] +
                                     double(d[2]) * d[2]);
      }
      point_motion_[k][i] = motion;
    }
  });
}

Vec3 LgiSolver::Predict(int k, const IndexCandidate& candidate, int j) const {
  const BundleIndex& b = index_.bundles[k];
  const CloudSimplex& s = b.simplices()[candidate.simplex];
  Vec3 x = data_.site_neutral.row(j).transpose();
  for (int i = 0; i < s.size; ++i) {
    const int shape = b.point_shapes()[s.corner[i]];
    if (shape >= 0 && candidate.weights[i] != 0.0) {
      x += candidate.weights[i] * data_.SiteDisplacement(shape, j);
    }
  }
  return x;
}

void LgiSolver::Assign(int k, const IndexCandidate& candidate, double cost,
                       BundleSolve* out, int representative) const {
  const BundleIndex& b = index_.bundles[k];
  out->simplex = candidate.simplex;
  out->cost = cost;
  out->corner_shapes.clear();
  out->weights.clear();
  if (representative != kNoRepresentative) {
    out->corner_shapes.push_back(representative);
    if (representative >= 0) out->weights.emplace_back(representative, 1.0);
    return;
  }
  const CloudSimplex& s = b.simplices()[candidate.simplex];
  for (int i = 0; i < s.size; ++i) {
    const int shape = b.point_shapes()[s.corner[i]];
    out->corner_shapes.push_back(shape);
    if (shape >= 0 && candidate.weights[i] > 0) {
      out->weights.emplace_back(shape, candidate.weights[i]);
    }
  }
  std::sort(out->weights.begin(), out->weights.end());
}

IndexQuery LgiSolver::GatherCandidates(int k, const Vec3& unskinned) const {
  const BundleIndex& b = index_.bundles[k];
  IndexQuery q = b.Query(unskinned, options_.outside_slack_mm, index_options_);
  // Cloud points within the pruning thresholds also compete: a shape
  // merged into a point (or pruned into the neutral) may put the bundle up
  // to that far from it, so the point is as valid an explanation as the
  // simplices that contain the bundle.
  const double snap =
      std::max(index_options_.merge_mm, index_options_.region_tag_mm);
  for (int i = 0; i < b.NumPoints(); ++i) {
    const double d = (b.points().row(i).transpose() - unskinned).norm();
    if (d > snap || d <= index_options_.on_data_mm) continue;
    IndexCandidate cand;
    cand.simplex = b.PointSimplex(i);
    cand.weights = {1, 0, 0, 0};
    cand.point = b.points().row(i).transpose();
    cand.distance = d;
    q.candidates.push_back(cand);
  }
  return q;
}

double LgiSolver::NeighbourCosts(int k, const IndexQuery& q,
                                 const std::vector<char>& observed,
                                 const std::vector<Vec3>& unskinned,
                                 std::vector<double>* costs,
                                 std::vector<int>* representatives,
                                 std::vector<std::vector<int>>* tied) const {
  const BundleIndex& b = index_.bundles[k];
  // Neighbour criterion sum_j |x0(s_j) + sum_i w_i D_i(s_j) - p*_j|^2 as
  // c + 2 w.g + w' G w over the candidate's corners (G precomputed; a
  // missing neighbour's terms are removed).
  const std::vector<int>& nbrs = neighbours_[k];
  const int J = static_cast<int>(nbrs.size());
  Eigen::VectorXd a = Eigen::VectorXd::Zero(3 * J);
  bool all_observed = true;
  for (int jj = 0; jj < J; ++jj) {
    const int j = nbrs[jj];
    if (!observed[j]) {
      all_observed = false;
      continue;
    }
    a.segment<3>(3 * jj) = data_.site_neutral.row(j).transpose() - unskinned[j];
  }
  const Eigen::MatrixXd& disp = site_disp_[k];
  Eigen::MatrixXd gram_missing;
  if (!all_observed) {
    gram_missing = gram_[k];
    for (int jj = 0; jj < J; ++jj) {
      if (observed[nbrs[jj]]) continue;
      const auto block = disp.middleCols(3 * jj, 3);
      gram_missing -= block * block.transpose();
    }
  }
  const Eigen::MatrixXd& gram = all_observed ? gram_[k] : gram_missing;
  const Eigen::VectorXd g = disp * a;
  const double c0 = a.squaredNorm();
  std::vector<double>& cost = *costs;
  std::vector<int>& rep = *representatives;
  cost.assign(q.candidates.size(), 0.0);
  rep.assign(q.candidates.size(), kNoRepresentative);
  tied->assign(q.candidates.size(), {});
  std::vector<std::pair<int, double>> alternatives;  // shape, cost
  double best = std::numeric_limits<double>::infinity();
  for (size_t ci = 0; ci < q.candidates.size(); ++ci) {
    const IndexCandidate& cand = q.candidates[ci];
    const CloudSimplex& s = b.simplices()[cand.simplex];
    double e = c0;
    for (int i = 0; i < s.size; ++i) {
      const double wi = cand.weights[i];
      if (wi == 0.0) continue;
      e += 2 * wi * g[s.corner[i]];
      for (int l = 0; l < s.size; ++l) {
        e += wi * cand.weights[l] * gram(s.corner[i], s.corner[l]);
      }
    }
    e = std::max(e, 0.0);
    // The candidate's own miss: its squared distance from the bundle.
    double own = cand.distance * cand.distance;
    // On one cloud point: any shape the point stands for may be the one
    // observed (verification of a merged or pruned shape depends on it),
    // scored by the neighbours and by its own surface point, which lies up
    // to the merge or pruning threshold from the cloud point: a shape
    // pruned into the neutral that moves the bundle and not its neighbours
    // ties with the neutral on the neighbours alone.
    int on_point = -1;
    for (int i = 0; i < s.size; ++i) {
      if (cand.weights[i] >= 1.0 - 1e-9) on_point = s.corner[i];
    }
    alternatives.clear();
    if (on_point >= 0) {
      alternatives.emplace_back(kNoRepresentative, e + own);
      // alt_point_[k] is sorted: the point's alternatives are one run.
      const auto run = std::equal_range(alt_point_[k].begin(),
                                        alt_point_[k].end(), on_point);
      for (auto it = run.first; it != run.second; ++it) {
        const size_t ai = static_cast<size_t>(it - alt_point_[k].begin());
        double ea = 0;
        for (int jj = 0; jj < J; ++jj) {
          if (!observed[nbrs[jj]]) continue;
          ea += (a.segment<3>(3 * jj) +
                 alt_disp_[k].block<1, 3>(ai, 3 * jj).transpose())
                    .squaredNorm();
        }
        const double own_a = (alt_site_[k][ai] - unskinned[k]).squaredNorm();
        alternatives.emplace_back(alt_shape_[k][ai], ea + own_a);
        if (ea + own_a < e + own - options_.tie_mm2) {
          e = ea;
          own = own_a;
          rep[ci] = alt_shape_[k][ai];
        }
      }
    }
    e += own;
    for (const auto& [shape, cost_a] : alternatives) {
      if (shape != rep[ci] && cost_a <= e + options_.tie_mm2) {
        (*tied)[ci].push_back(shape);
      }
    }
    cost[ci] = e;
    best = std::min(best, e);
  }
  return best;
}

int LgiSolver::TemporalChoice(int k, const IndexQuery& q,
                              const std::vector<double>& cost, double best,
                              const FrameSolve* previous,
                              std::vector<int>* shared_shapes) const {
  const BundleIndex& b = index_.bundles[k];
  // The winding-number preference: among near-best candidates, the one
  // sharing the most shapes with the previous frame's choice.
  // It applies while the bundle is still on the previous frame's simplex
  // (that simplex is a candidate now): across a discontinuity (a cut,
  // unrelated frames) the frames are solved independently.
  const std::vector<int>* prev_shapes = nullptr;
  if (previous != nullptr && options_.temporal_preference > 0 &&
      !previous->bundles[k].corner_shapes.empty()) {
    const int prev_simplex = previous->bundles[k].simplex;
    for (const IndexCandidate& cand : q.candidates) {
      if (cand.simplex == prev_simplex) {
        prev_shapes = &previous->bundles[k].corner_shapes;
        break;
      }
    }
  }
  const double limit =
      prev_shapes
          ? best * (1 + options_.temporal_preference) + options_.tie_mm2
          : best + options_.tie_mm2;
  std::vector<int>& shared = *shared_shapes;
  shared.assign(q.candidates.size(), 0);
  int chosen = -1;
  for (size_t c = 0; c < q.candidates.size(); ++c) {
    if (cost[c] > limit) continue;
    if (prev_shapes) {
      const CloudSimplex& s = b.simplices()[q.candidates[c].simplex];
      for (int i = 0; i < s.size; ++i) {
        const int shape = b.point_shapes()[s.corner[i]];
        shared[c] += std::count(prev_shapes->begin(), prev_shapes->end(),
                                shape) > 0;
      }
    }
    // Candidates are sorted by simplex id, so ties keep the lowest id.
    if (chosen < 0 || shared[c] > shared[chosen] ||
        (shared[c] == shared[chosen] && cost[c] < cost[chosen])) {
      chosen = static_cast<int>(c);
    }
  }
  return chosen;
}

void LgiSolver::BreakTies(const TieGroups& tie, FrameSolve* frame) const {
  const int K = data_.num_bundles;
  FrameSolve& f = *frame;
  // Ties: a bundle whose position and neighbours cannot tell candidates
  // apart (a shape that moves only the skin between bundles leaves them all
  // where the neutral has them) takes the candidate whose points stand for
  // the shapes the untied bundles of the frame chose (the frame's consensus),
  // then the one moving its region least.
  auto same_blend = [](const std::vector<std::pair<int, double>>& a,
                       const std::vector<std::pair<int, double>>& b) {
    if (a.size() != b.size()) return false;
    for (size_t i = 0; i < a.size(); ++i) {
      if (a[i].first != b[i].first ||
          std::abs(a[i].second - b[i].second) > 1e-12) {
        return false;
      }
    }
    return true;
  };
  std::vector<char> tied(K, 0);
  ParallelFor(0, K, [&](int64_t k) {
    if (tie.candidates[k].size() < 2) return;
    BundleSolve first_blend, probe;
    Assign(static_cast<int>(k), tie.candidates[k][0], 0.0, &first_blend, tie.representative[k][0]);
    for (size_t t = 0; t < tie.candidates[k].size(); ++t) {
      if (!tie.primary[k][t]) continue;
      Assign(static_cast<int>(k), tie.candidates[k][t], 0.0, &probe, tie.representative[k][t]);
      if (!same_blend(probe.weights, first_blend.weights)) {
        tied[k] = 1;
        return;
      }
    }
  });
  std::vector<double> consensus(data_.num_shapes + 1, 0.0);  // [shape + 1]
  // Of those votes, the ones for a shape whose bundle moved: a chosen
  // representative, or a shape the chosen point stands for when that point
  // is not the neutral's. A shape that moves only the skin between bundles
  // stands with the neutral on every point and has none. Which of a merged
  // point's shapes labels it is arbitrary (the first kept), so every shape
  // the point stands for gets the vote.
  std::vector<double> explicit_votes(data_.num_shapes + 1, 0.0);
  for (int k = 0; k < K; ++k) {
    if (tied[k] || !f.bundles[k].Measured()) continue;
    if (tie.chosen_representative[k] != kNoRepresentative) {
      if (tie.chosen_representative[k] >= 0) {
        consensus[tie.chosen_representative[k] + 1] += 1.0;
        explicit_votes[tie.chosen_representative[k] + 1] += 1.0;
      }
      continue;
    }
    const BundleIndex& b = index_.bundles[k];
    const CloudSimplex& s = b.simplices()[f.bundles[k].simplex];
    // The chosen candidate's weights per corner, recovered from the shapes.
    for (int i = 0; i < s.size; ++i) {
      const int shape = b.point_shapes()[s.corner[i]];
      double w = 0;
      if (shape < 0) {
        w = 1.0;
        for (const auto& [n, wn] : f.bundles[k].weights) w -= wn;
      } else {
        for (const auto& [n, wn] : f.bundles[k].weights) {
          if (n == shape) w = wn;
        }
      }
      // Only the neutral's point (shape -1) stands for the neutral.
      for (int r : index_.represented[k][s.corner[i]]) {
        consensus[r + 1] += w;
        if (shape >= 0) explicit_votes[r + 1] += w;
      }
    }
  }
  // A tie entry standing on a point for another of its shapes (not the
  // candidate's own choice) competes with the point's own blend only for a
  // shape some untied bundle chose as itself.
  auto contends = [&](int r) { return r >= 0 && explicit_votes[r + 1] > 0; };
  ParallelFor(0, K, [&](int64_t k) {
    if (!tied[k]) return;
    const BundleIndex& b = index_.bundles[k];
    // Whether an entry stands on simplex `simplex` for shape r.
    std::vector<std::pair<int, int>> entries;  // (simplex, representative)
    for (size_t t = 0; t < tie.candidates[k].size(); ++t) {
      entries.emplace_back(tie.candidates[k][t].simplex,
                           tie.representative[k][t]);
    }
    std::sort(entries.begin(), entries.end());
    auto has_entry = [&](int simplex, int r) {
      return std::binary_search(entries.begin(), entries.end(),
                                std::make_pair(simplex, r));
    };
    int best_t = -1;
    double best_score = 0, best_motion = 0;
    for (size_t t = 0; t < tie.candidates[k].size(); ++t) {
      if (!tie.primary[k][t] && !contends(tie.representative[k][t])) continue;
      const IndexCandidate& cand = tie.candidates[k][t];
      const CloudSimplex& s = b.simplices()[cand.simplex];
      double score = 0, motion = 0;
      for (int i = 0; i < s.size; ++i) {
        const double w = cand.weights[i];
        motion += w * point_motion_[k][s.corner[i]];
        const int r = tie.representative[k][t];
        if (r != kNoRepresentative) {
          // On one point, standing for shape r.
          if (r >= 0 && w > 0.5) score += consensus[r + 1];
          continue;
        }
        // The neutral carries no evidence ("nothing moved" is what most
        // bundles see of any local shape), so only shapes count. A shape
        // the point stands for that ties as an entry of its own (on this
        // point, as its representative) lends its support to that entry
        // only: blending the point's shape is not blending it.
        double support = 0;
        for (int r : index_.represented[k][s.corner[i]]) {
          if (r < 0 || (w >= 1.0 - 1e-9 && contends(r) &&
                        has_entry(cand.simplex, r))) {
            continue;
          }
          support = std::max(support, consensus[r + 1]);
        }
        score += w * support;
      }
      bool better = best_t < 0 || score > best_score + 1e-9;
      if (!better && score >= best_score - 1e-9) {
        const int sh = tie.shared[k][t], best_sh = tie.shared[k][best_t];
        better = sh > best_sh ||
                 (sh == best_sh && motion < best_motion - 1e-12);
      }
      if (better) {
        best_t = static_cast<int>(t);
        best_score = score;
        best_motion = motion;
      }
    }
    Assign(static_cast<int>(k), tie.candidates[k][best_t], tie.cost[k][best_t],
           &f.bundles[k], tie.representative[k][best_t]);
  });
}

void LgiSolver::FillMissing(FrameSolve* frame) const {
  const int K = data_.num_bundles;
  FrameSolve& f = *frame;
  // Missing bundles: the neighbours' weights, averaged by inverse squared
  // distance between the sites on the neutral.
  std::vector<int> solved;
  for (int k = 0; k < K; ++k) {
    if (f.bundles[k].Measured()) solved.push_back(k);
  }
  for (int k = 0; k < K; ++k) {
    BundleSolve& out = f.bundles[k];
    if (out.status != BundleSolve::Status::kUnused) continue;
    std::vector<int> from;
    for (int j : nn_.site_neighbours[k]) {
      if (j != k && f.bundles[j].Measured()) from.push_back(j);
    }
    if (from.empty()) {
      // No solved natural neighbour: the nearest solved bundle.
      double nearest = std::numeric_limits<double>::infinity();
      for (int j : solved) {
        const double d =
            (data_.site_neutral.row(j) - data_.site_neutral.row(k)).norm();
        if (d < nearest) {
          nearest = d;
          from = {j};
        }
      }
    }
    std::map<int, double> acc;
    double total = 0;
    for (int j : from) {
      const double d2 =
          (data_.site_neutral.row(j) - data_.site_neutral.row(k)).squaredNorm();
      const double w = 1.0 / std::max(d2, 1e-12);
      total += w;
      for (const auto& [shape, wn] : f.bundles[j].weights) acc[shape] += w * wn;
    }
    out.status = BundleSolve::Status::kFilled;
    for (const auto& [shape, w] : acc) out.weights.emplace_back(shape, w / total);
  }
}

FrameSolve LgiSolver::SolveFrame(const BundleFrame& bundles,
                                 const JawPose& jaw,
                                 const FrameSolve* previous) const {
  const int K = data_.num_bundles;
  FrameSolve f;
  const std::vector<char> observed =
      BeginFrame(bundles, jaw, marker_index_, K, &f);
  std::vector<Vec3> unskinned(K, Vec3::Zero());
  int num_observed = 0;
  for (int k = 0; k < K; ++k) {
    if (!observed[k]) continue;
    ++num_observed;
    unskinned[k] = UnskinBundle(data_, k, jaw, f.bundles[k].observed);
  }
  const int needed = BundlesNeeded(options_.min_bundle_fraction, K);
  if (num_observed < needed) {
    f.ok = false;
    f.reason = fmt::format("only {} of {} bundles observed (need {})",
                           num_observed, K, needed);
    return f;
  }

  TieGroups tie(K);
  ParallelFor(0, K, [&](int64_t k) {
    if (!observed[k]) return;
    BundleSolve& out = f.bundles[k];
    const IndexQuery q = GatherCandidates(static_cast<int>(k), unskinned[k]);
    out.num_candidates = static_cast<int>(q.candidates.size());
    if (q.candidates.empty()) return;  // filled from the neighbours below
    std::vector<double> cost;
    std::vector<int> rep, shared;
    std::vector<std::vector<int>> tied;
    const double best = NeighbourCosts(static_cast<int>(k), q, observed,
                                       unskinned, &cost, &rep, &tied);
    const int chosen =
        TemporalChoice(static_cast<int>(k), q, cost, best, previous, &shared);
    // The exact tie group (cost within tie_mm2 of the best): settled below,
    // once every bundle has a first choice, if its blends differ.
    for (size_t c = 0; c < q.candidates.size(); ++c) {
      if (cost[c] > best + options_.tie_mm2) continue;
      tied[c].insert(tied[c].begin(), rep[c]);
      for (int r : tied[c]) {
        tie.candidates[k].push_back(q.candidates[c]);
        tie.representative[k].push_back(r);
        tie.cost[k].push_back(cost[c]);
        tie.shared[k].push_back(shared[c]);
        tie.primary[k].push_back(r == rep[c]);
      }
    }
    out.status = q.inside ? BundleSolve::Status::kInside
                          : BundleSolve::Status::kProjected;
    out.distance = q.distance;
    Assign(static_cast<int>(k), q.candidates[chosen], cost[chosen], &out,
           rep[chosen]);
    tie.chosen_representative[k] = rep[chosen];
  });
  BreakTies(tie, &f);
  FillMissing(&f);
  f.ok = true;
  return f;
}

MatX3d LgiSolver::Blend(FrameSolve* frame) const {
  const int V = data_.num_vertices, N = data_.num_shapes;
  MatX3d out(V, 3);
  const JawRig* rig = data_.jaw_rig ? &*data_.jaw_rig : nullptr;
  const Rigid3 t = rig ? rig->Transform(frame->jaw) : Rigid3::Identity();
  const Mat3 r = t.linear();
  const Vec3 tr = t.translation();
  ParallelFor(
      0, V,
      [&](int64_t v) {
        Vec3 x = neutral_.V.row(v).transpose();
        const int first = data_.vertex_shape_start[v];
        const int last = data_.vertex_shape_start[v + 1];
        // A vertex no shape moves (44 % of the default actor's) needs no
        // weights. The others: each shape's coefficient sum_k lambda_k(v)
        // u_kn gathered first, then one pass over the shapes that move v.
        if (first < last) {
          thread_local std::vector<double> coefficient;
          coefficient.resize(N, 0.0);
          for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(
                   nn_.weights, v);
               it; ++it) {
            for (const auto& [n, w] : frame->bundles[it.col()].weights) {
              coefficient[n] += it.value() * w;
            }
          }
          for (int j = first; j < last; ++j) {
            const double c = coefficient[data_.vertex_shapes[j]];
            const float* bn = &data_.vertex_shape_displacement[3 * j];
            x[0] += c * bn[0];
            x[1] += c * bn[1];
            x[2] += c * bn[2];
          }
          for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(
                   nn_.weights, v);
               it; ++it) {
            for (const auto& [n, w] : frame->bundles[it.col()].weights) {
              coefficient[n] = 0.0;
            }
          }
        }
        if (rig) {
          const double wv = rig->weights[v];
          x = (1.0 - wv) * x + wv * (r * x + tr);
        }
        out.row(v) = x.transpose();
      },
      512);
  SetResiduals(data_.sites, neutral_.F, out, frame);
  return out;
}

void LgiSolver::SmoothWeights(int window, std::vector<FrameSolve>* frames) {
  if (window <= 1 || frames->empty()) return;
  const int half = window / 2;
  const int F = static_cast<int>(frames->size());
  const int K = static_cast<int>((*frames)[0].bundles.size());
  std::vector<std::vector<std::vector<std::pair<int, double>>>> original(F);
  for (int f = 0; f < F; ++f) {
    for (const auto& b : (*frames)[f].bundles) original[f].push_back(b.weights);
  }
  ParallelFor(0, K, [&](int64_t k) {
    for (int f = 0; f < F; ++f) {
      if (!(*frames)[f].ok) continue;
      std::map<int, double> acc;
      int count = 0;
      for (int g = std::max(0, f - half); g <= std::min(F - 1, f + half); ++g) {
        if (!(*frames)[g].ok) continue;
        ++count;
        for (const auto& [shape, w] : original[g][k]) acc[shape] += w;
      }
      auto& weights = (*frames)[f].bundles[k].weights;
      weights.clear();
      for (const auto& [shape, w] : acc) weights.emplace_back(shape, w / count);
    }
  });
}

SolveResult LgiSolver::SolveSequence(
    const std::vector<BundleFrame>& frames, const std::vector<JawPose>& jaw,
    const std::vector<std::string>& frame_errors) const {
  SolveResult result;
  // Steps 1-4, in order: the temporal preference looks at the previous
  // good frame's choices.
  const FrameSolve* previous = nullptr;
  SolveFrames(
      frames, jaw, frame_errors, data_.num_bundles, "lgi choice",
      [&](int f, const JawPose& pose, FrameSolve* out) {
        *out = SolveFrame(frames[f], pose, previous);
        if (out->ok) previous = out;
      },
      &result);
  // Step 5, then step 6 on the good frames; the bad ones repeat the
  // previous good mesh.
  SmoothWeights(options_.smooth_window, &result.frames);
  const int F = static_cast<int>(frames.size());
  result.meshes.resize(F);
  SolveSummary& s = result.summary;
  s.frames = F;
  Progress progress("lgi blend", F);
  for (int f = 0; f < F; ++f) {
    FrameSolve& fs = result.frames[f];
    if (fs.ok) result.meshes[f] = Blend(&fs);
    s.Count(fs);
    progress.Advance();
  }
  FillBadMeshes(neutral_, data_.jaw_rig ? &*data_.jaw_rig : nullptr, &result);
  return result;
}

}  // namespace hmc
