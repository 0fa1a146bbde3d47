#include "blending/baseline_blendshape.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <set>

#include "core/error.h"
#include "core/jaw.h"
#include "core/logging.h"
#include "core/parallel.h"

namespace hmc {

void BlendshapeOptions::Register(OptionFields* fields) {
  fields->SetGroup("blendshape");
  fields->Add("bounded", &bounded,
              "hard bounds 0 <= w <= 1 instead of the soft penalty");
  fields->Add("penalty", &penalty,
              "soft [0,1] penalty weight (mm^2 per unit weight^2)")
      .AtLeast(0);
  fields->Add("tikhonov", &tikhonov,
              "|w|^2 regulariser for conditioning (mm^2 per unit weight^2)")
      .Above(0);
  fields->Add("max_iterations", &max_iterations,
              "solver iterations per frame (Newton steps of the soft fit, "
              "active-set updates of the bounded one)")
      .AtLeast(1);
  fields->SetGroup("");
}

bool BlendshapeOptions::Check() const {
  CHECK_OPTION_LIMITS();
  CHECK_OPTION_IN(min_bundle_fraction, 0.0, 1.0);
  return true;
}

namespace {

// A shape enters a fit of bounded size (options.max_shapes) when more than
// this share of its motion at the bundles is new (docs/method.md, "A global
// fit of bounded size").
constexpr double kMinNewShare = 0.05;

double SoftObjective(const Eigen::MatrixXd& Q, const Eigen::VectorXd& c,
                     double mu, const Eigen::VectorXd& w) {
  double pen = 0;
  for (int i = 0; i < w.size(); ++i) {
    if (w[i] < 0) pen += w[i] * w[i];
    if (w[i] > 1) pen += (w[i] - 1) * (w[i] - 1);
  }
  return 0.5 * w.dot(Q * w) - c.dot(w) + 0.5 * mu * pen;
}

}  // namespace

Eigen::VectorXd SolveSoftBoxQp(const Eigen::MatrixXd& Q,
                               const Eigen::VectorXd& c, double mu,
                               int max_iterations) {
  const int N = static_cast<int>(c.size());
  Eigen::VectorXd w = Eigen::VectorXd::Zero(N);
  double f = SoftObjective(Q, c, mu, w);
  // Active sets of the current point; the objective is the quadratic
  // 1/2 w^T (Q + mu D) w - (c + mu h)^T w on the region where they hold.
  for (int iter = 0; iter < max_iterations; ++iter) {
    Eigen::MatrixXd A = Q;
    Eigen::VectorXd b = c;
    for (int i = 0; i < N; ++i) {
      if (w[i] < 0) {
        A(i, i) += mu;
      } else if (w[i] > 1) {
        A(i, i) += mu;
        b[i] += mu;
      }
    }
    const Eigen::VectorXd target = A.llt().solve(b);
    const Eigen::VectorXd step = target - w;
    if (step.lpNorm<Eigen::Infinity>() < 1e-13) break;
    // The gradient is continuous and the objective convex, so a backtracking
    // line search along the Newton direction always makes progress.
    double t = 1.0;
    Eigen::VectorXd next = target;
    double f_next = SoftObjective(Q, c, mu, next);
    for (int halving = 0; halving < 40 && f_next > f; ++halving) {
      t *= 0.5;
      next = w + t * step;
      f_next = SoftObjective(Q, c, mu, next);
    }
    if (f_next > f) break;
    w = next;
    const bool converged = t == 1.0 && f - f_next <= 1e-15 * (1 + std::abs(f));
    f = f_next;
    if (converged) break;
  }
  return w;
}

namespace {

enum class Bound : char { kFree, kLower, kUpper };

// The minimiser of 1/2 w^T Q w - c^T w with the bounded variables held at
// their bounds (0 or 1) and the free ones solved for.
Eigen::VectorXd SolveOnFreeSet(const Eigen::MatrixXd& Q,
                               const Eigen::VectorXd& c,
                               const std::vector<Bound>& state) {
  const int N = static_cast<int>(c.size());
  Eigen::VectorXd w = Eigen::VectorXd::Zero(N);
  std::vector<int> free, upper;
  for (int i = 0; i < N; ++i) {
    if (state[i] == Bound::kFree) free.push_back(i);
    if (state[i] == Bound::kUpper) {
      upper.push_back(i);
      w[i] = 1.0;
    }
  }
  if (free.empty()) return w;
  const int M = static_cast<int>(free.size());
  Eigen::MatrixXd Qff(M, M);
  Eigen::VectorXd r(M);
  for (int a = 0; a < M; ++a) {
    r[a] = c[free[a]];
    for (int u : upper) r[a] -= Q(free[a], u);
    for (int b = 0; b < M; ++b) Qff(a, b) = Q(free[a], free[b]);
  }
  const Eigen::VectorXd wf = Qff.llt().solve(r);
  for (int a = 0; a < M; ++a) w[free[a]] = wf[a];
  return w;
}

// Primal active set method (Nocedal & Wright 2006, algorithm 16.3) from the
// feasible point w: monotone, finite; the fallback when the primal-dual
// iteration does not settle.
Eigen::VectorXd PrimalActiveSet(const Eigen::MatrixXd& Q,
                                const Eigen::VectorXd& c, Eigen::VectorXd w,
                                int max_iterations) {
  const int N = static_cast<int>(c.size());
  std::vector<Bound> state(N, Bound::kFree);
  for (int i = 0; i < N; ++i) {
    if (w[i] <= 0) state[i] = Bound::kLower, w[i] = 0;
    if (w[i] >= 1) state[i] = Bound::kUpper, w[i] = 1;
  }
  const double tol = 1e-12 * (1.0 + c.lpNorm<Eigen::Infinity>());
  for (int iter = 0; iter < max_iterations; ++iter) {
    const Eigen::VectorXd target = SolveOnFreeSet(Q, c, state);
    // Step toward the target until the first free variable meets a bound.
    double step = 1.0;
    int blocking = -1;
    for (int i = 0; i < N; ++i) {
      if (state[i] != Bound::kFree) continue;
      const double d = target[i] - w[i];
      const double room = d < 0 ? -w[i] / d : d > 0 ? (1.0 - w[i]) / d : 1.0;
      if (room < step) step = room, blocking = i;
    }
    const bool lower = blocking >= 0 && target[blocking] < w[blocking];
    w += step * (target - w);
    if (blocking >= 0) {
      state[blocking] = lower ? Bound::kLower : Bound::kUpper;
      w[blocking] = lower ? 0.0 : 1.0;
      continue;
    }
    // At the minimiser of the working set: release the bound whose
    // multiplier has the wrong sign the most.
    const Eigen::VectorXd g = Q * w - c;
    int release = -1;
    double worst = tol;
    for (int i = 0; i < N; ++i) {
      const double wrong = state[i] == Bound::kLower   ? -g[i]
                           : state[i] == Bound::kUpper ? g[i]
                                                       : 0.0;
      if (wrong > worst) worst = wrong, release = i;
    }
    if (release < 0) break;
    state[release] = Bound::kFree;
  }
  return w;
}

}  // namespace

Eigen::VectorXd SolveBoundedBoxQp(const Eigen::MatrixXd& Q,
                                  const Eigen::VectorXd& c, int max_iterations,
                                  const Eigen::VectorXd* start) {
  const int N = static_cast<int>(c.size());
  // Warm-started (for example from the previous frame's weights): the
  // primal active set method from there, which changes one bound per
  // solve and so takes about as many solves as the start has bounds wrong.
  // (From the previous frame, the primal-dual iteration below went through
  // ~34 working sets per frame of BM_RobustSequence before cycling, in two
  // frames of three.)
  if (start) {
    HMC_CHECK(start->size() == N);
    return PrimalActiveSet(Q, c, start->cwiseMax(0.0).cwiseMin(1.0),
                           4 * N + max_iterations);
  }
  // Cold: primal-dual active set (Hintermueller, Ito & Kunisch 2002) from
  // the unconstrained minimiser, scaled by Q's diagonal: the bounds
  // predicted by one projected Newton step of the current point,
  // z = w - g / diag(Q), are held and the rest solved for, until the
  // prediction repeats. That point satisfies the KKT conditions exactly.
  const Eigen::VectorXd w0 = Q.llt().solve(c);
  std::vector<Bound> state(N, Bound::kFree);
  for (int i = 0; i < N; ++i) {
    if (w0[i] <= 0) state[i] = Bound::kLower;
    if (w0[i] >= 1) state[i] = Bound::kUpper;
  }
  // Tolerance on the prediction: a free variable a rounding error outside
  // its bound, or a held one whose multiplier is a rounding error of the
  // wrong sign, does not flip.
  const double eps = 1e-12;
  Eigen::VectorXd w;
  // The working sets tried: the iteration is deterministic, so meeting one
  // again means it cycles (possible when Q is far from an M-matrix) and
  // would run to its iteration cap.
  std::set<std::vector<Bound>> tried;
  for (int iter = 0; iter < max_iterations; ++iter) {
    if (!tried.insert(state).second) break;
    w = SolveOnFreeSet(Q, c, state);
    const Eigen::VectorXd g = Q * w - c;
    bool changed = false;
    for (int i = 0; i < N; ++i) {
      const double z = w[i] - g[i] / Q(i, i);
      const Bound next = z < -eps       ? Bound::kLower
                         : z > 1.0 + eps ? Bound::kUpper
                                         : Bound::kFree;
      if (next != state[i]) {
        state[i] = next;
        changed = true;
      }
    }
    if (!changed) return w.cwiseMax(0.0).cwiseMin(1.0);
  }
  // Did not settle (it cycled, or reached the cap): the monotone method
  // from the last point, clamped.
  return PrimalActiveSet(Q, c, w.cwiseMax(0.0).cwiseMin(1.0),
                         4 * N + max_iterations);
}

SolveResult RunBaselineSequence(const ShapeData& data, const TriMesh& neutral,
                                const std::vector<BundleFrame>& frames,
                                const std::vector<JawPose>& jaw,
                                const std::vector<std::string>& frame_errors,
                                const BaselineFrameFn& solve,
                                const std::string& name) {
  const int F = static_cast<int>(frames.size());
  SolveResult result;
  result.meshes.resize(F);
  SolveFrames(
      frames, jaw, frame_errors, data.num_bundles, name,
      [&](int f, const JawPose& pose, FrameSolve* out) {
        *out = solve(f, frames[f], pose, &result.meshes[f]);
      },
      &result);
  SolveSummary& s = result.summary;
  s.frames = F;
  for (const FrameSolve& fs : result.frames) {
    for (const BundleSolve& b : fs.bundles) {
      if (b.status == BundleSolve::Status::kInside) ++s.bundles_inside;
    }
  }
  FillBadMeshes(neutral, data.jaw_rig ? &*data.jaw_rig : nullptr, &result);
  return result;
}

std::vector<int> SelectSpanningShapes(const Eigen::MatrixXd& site_shapes,
                                      int max_shapes, double min_new) {
  const int N = static_cast<int>(site_shapes.cols());
  std::vector<int> kept;
  if (max_shapes <= 0 || N <= max_shapes) {
    for (int n = 0; n < N; ++n) kept.push_back(n);
    return kept;
  }
  // An orthonormal basis of the kept shapes' span (modified Gram-Schmidt,
  // twice: one pass loses orthogonality on nearly dependent shapes).
  Eigen::MatrixXd basis(site_shapes.rows(), max_shapes);
  for (int n = 0; n < N && static_cast<int>(kept.size()) < max_shapes; ++n) {
    const double norm = site_shapes.col(n).norm();
    if (!(norm > 0)) continue;
    Eigen::VectorXd r = site_shapes.col(n);
    for (int pass = 0; pass < 2; ++pass) {
      for (size_t i = 0; i < kept.size(); ++i) {
        r -= basis.col(static_cast<int>(i)).dot(r) * basis.col(static_cast<int>(i));
      }
    }
    const double left = r.norm();
    if (!(left > min_new * norm)) continue;
    basis.col(static_cast<int>(kept.size())) = r / left;
    kept.push_back(n);
  }
  return kept;
}

BlendshapeSolver::BlendshapeSolver(const TriMesh& neutral,
                                   const ShapeData& data,
                                   const BlendshapeOptions& options)
    : neutral_(neutral), data_(data), options_(options) {
  const int K = data.num_bundles;
  HMC_CHECK(neutral.NumVertices() == data.num_vertices);
  for (int k = 0; k < K; ++k) marker_index_[data.bundle_names[k]] = k;
  site_shapes_.resize(3 * K, data.num_shapes);
  for (int n = 0; n < data.num_shapes; ++n) {
    for (int k = 0; k < K; ++k) {
      site_shapes_.block<3, 1>(3 * k, n) = data.SiteDisplacement(n, k);
    }
  }
  shapes_ = SelectSpanningShapes(site_shapes_, options.max_shapes,
                                 kMinNewShare);
  if (static_cast<int>(shapes_.size()) < data.num_shapes) {
    Eigen::MatrixXd kept(3 * K, shapes_.size());
    for (size_t i = 0; i < shapes_.size(); ++i) {
      kept.col(static_cast<int>(i)) = site_shapes_.col(shapes_[i]);
    }
    site_shapes_ = std::move(kept);
  }
  normal_ = site_shapes_.transpose() * site_shapes_;
  normal_.diagonal().array() += options.tikhonov;
}

FrameSolve BlendshapeSolver::SolveFrame(const BundleFrame& bundles,
                                        const JawPose& jaw,
                                        Eigen::VectorXd* weights,
                                        MatX3d* mesh,
                                        const Eigen::VectorXd* start) const {
  const int K = data_.num_bundles;
  FrameSolve f;
  const std::vector<char> observed =
      BeginFrame(bundles, jaw, marker_index_, K, &f);
  Eigen::VectorXd d = Eigen::VectorXd::Zero(3 * K);
  int num_observed = 0;
  for (int k = 0; k < K; ++k) {
    if (!observed[k]) continue;
    ++num_observed;
    f.bundles[k].status = BundleSolve::Status::kInside;
    d.segment<3>(3 * k) = UnskinBundle(data_, k, jaw, f.bundles[k].observed) -
                          data_.site_neutral.row(k).transpose();
  }
  const int needed = BundlesNeeded(options_.min_bundle_fraction, K);
  if (num_observed < needed) {
    for (BundleSolve& b : f.bundles) b.status = BundleSolve::Status::kUnused;
    f.reason = fmt::format("only {} of {} bundles observed (need {})",
                           num_observed, K, needed);
    return f;
  }
  const Eigen::VectorXd w =
      FitWeights(observed, d, Eigen::VectorXd::Zero(num_shapes()), start);
  f.ok = true;
  if (mesh) {
    *mesh = Blend(w, jaw);
    SetResiduals(data_.sites, neutral_.F, *mesh, &f);
  }
  if (weights) *weights = w;
  return f;
}

Eigen::MatrixXd BlendshapeSolver::Normal(
    const std::vector<char>& observed) const {
  // Missing bundles have d = 0 and their rank-3 terms leave the normal
  // matrix.
  Eigen::MatrixXd H = normal_;
  for (int k = 0; k < data_.num_bundles; ++k) {
    if (observed[k]) continue;
    const auto Bk = site_shapes_.middleRows(3 * k, 3);
    H.noalias() -= Bk.transpose() * Bk;
  }
  return H;
}

Eigen::VectorXd BlendshapeSolver::FitWeights(
    const std::vector<char>& observed, const Eigen::VectorXd& d,
    const Eigen::VectorXd& ridge, const Eigen::VectorXd* start) const {
  HMC_CHECK(ridge.size() == num_shapes());
  Eigen::MatrixXd H = Normal(observed);
  H.diagonal() += ridge;
  const Eigen::VectorXd c = Project(d);
  // E = w^T H w - 2 c^T w + mu pen = 2 (1/2 w^T H w - c^T w + 1/2 mu pen).
  return options_.bounded
             ? SolveBoundedBoxQp(H, c, options_.max_iterations, start)
             : SolveSoftBoxQp(H, c, options_.penalty, options_.max_iterations);
}

std::vector<Vec3> BlendshapeSolver::LeaveOneOutResiduals(
    const std::vector<char>& observed, const Eigen::VectorXd& weights,
    const Eigen::VectorXd& ridge, const std::vector<Vec3>& residual) const {
  const int K = data_.num_bundles, N = num_shapes();
  // The free set is read from the bounds: only the bounded fit has them.
  HMC_CHECK(options_.bounded);
  HMC_CHECK(weights.size() == N && ridge.size() == N &&
            static_cast<int>(residual.size()) == K);
  std::vector<Vec3> out(K, Vec3::Zero());
  std::vector<int> free;
  for (int n = 0; n < N; ++n) {
    if (weights[n] > 0.0 && weights[n] < 1.0) free.push_back(n);
  }
  const int F = static_cast<int>(free.size());
  const Eigen::MatrixXd normal = Normal(observed);
  Eigen::MatrixXd m(F, F), bt(F, 3 * K);
  for (int a = 0; a < F; ++a) {
    for (int b = 0; b < F; ++b) m(a, b) = normal(free[a], free[b]);
    m(a, a) += ridge[free[a]];
    bt.row(a) = site_shapes_.col(free[a]).transpose();
  }
  // H_kk = W_k^T W_k with W = L^-1 B_F^T (M = L L^T).
  const Eigen::MatrixXd w =
      Eigen::LLT<Eigen::MatrixXd>(m).matrixL().solve(bt);
  for (int k = 0; k < K; ++k) {
    if (!observed[k]) continue;
    const auto wk = w.middleCols(3 * k, 3);
    const Mat3 h = wk.transpose() * wk;
    out[k] = (Mat3::Identity() - h).partialPivLu().solve(residual[k]);
  }
  return out;
}

MatX3d BlendshapeSolver::Blend(const Eigen::VectorXd& weights,
                               const JawPose& jaw) const {
  const int V = data_.num_vertices;
  HMC_CHECK(weights.size() == num_shapes());
  // Over every dataset shape (0 for those the solver leaves out).
  Eigen::VectorXd all = Eigen::VectorXd::Zero(data_.num_shapes);
  for (int i = 0; i < num_shapes(); ++i) all[shapes_[i]] = weights[i];
  MatX3d out(V, 3);
  ParallelFor(
      0, V,
      [&](int64_t v) {
        Vec3 x = neutral_.V.row(v).transpose();
        // The shapes that move v, those with a weight (the others add 0).
        for (int j = data_.vertex_shape_start[v];
             j < data_.vertex_shape_start[v + 1]; ++j) {
          const double w = all[data_.vertex_shapes[j]];
          if (w == 0) continue;
          const float* bn = &data_.vertex_shape_displacement[3 * j];
          x[0] += w * bn[0];
          x[1] += w * bn[1];
          x[2] += w * bn[2];
        }
        out.row(v) = x.transpose();
      },
      256);
  if (data_.jaw_rig) return Skin(*data_.jaw_rig, jaw, out);
  return out;
}

SolveResult BlendshapeSolver::SolveSequence(
    const std::vector<BundleFrame>& frames, const std::vector<JawPose>& jaw,
    const std::vector<std::string>& frame_errors,
    std::vector<Eigen::VectorXd>* weights) const {
  if (weights) {
    weights->assign(frames.size(), Eigen::VectorXd());
  }
  Eigen::VectorXd previous;  // the last good frame's weights
  return RunBaselineSequence(
      data_, neutral_, frames, jaw, frame_errors,
      [&](int index, const BundleFrame& b, const JawPose& pose, MatX3d* mesh) {
        Eigen::VectorXd w;
        FrameSolve fs = SolveFrame(b, pose, &w, mesh,
                                   previous.size() ? &previous : nullptr);
        if (!fs.ok) return fs;
        previous = w;
        if (weights) (*weights)[index] = std::move(w);
        return fs;
      },
      options_.bounded ? "blendshape-bounded" : "blendshape");
}

}  // namespace hmc
