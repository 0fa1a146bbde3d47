#include "blending/baseline_interp.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>

#include "blending/baseline_blendshape.h"
#include "core/error.h"
#include "core/jaw.h"
#include "core/parallel.h"

namespace hmc {

void InterpOptions::Register(OptionFields* fields) {
  fields->SetGroup("interp");
  fields->Add("merge_mm", &merge_mm,
              "bundles whose sites on the neutral are closer than this share "
              "one constraint (mm)")
      .AtLeast(0);
  fields->SetGroup("");
}

bool InterpOptions::Check() const {
  CHECK_OPTION_LIMITS();
  CHECK_OPTION_IN(min_bundle_fraction, 0.0, 1.0);
  return true;
}

namespace {

// The symmetric (n+4) x (n+4) system over the bundles `ids`:
//   [G_ss   P_s] [alpha]   [d_s]
//   [P_s^T   0 ] [beta ] = [ 0 ]
// G: the kernel between the surface-point functionals; P_s rows
// (1, x0(s_k)) (the functional of an affine function at its surface point).
Eigen::MatrixXd System(const Eigen::MatrixXd& collocation,
                       const MatX3d& centres, const std::vector<int>& ids) {
  const int n = static_cast<int>(ids.size());
  Eigen::MatrixXd M = Eigen::MatrixXd::Zero(n + 4, n + 4);
  for (int a = 0; a < n; ++a) {
    for (int b = 0; b < n; ++b) M(a, b) = collocation(ids[a], ids[b]);
    M(a, n) = 1;
    M(n, a) = 1;
    for (int i = 0; i < 3; ++i) {
      M(a, n + 1 + i) = centres(ids[a], i);
      M(n + 1 + i, a) = centres(ids[a], i);
    }
  }
  return M;
}

}  // namespace

InterpSolver::InterpSolver(const TriMesh& neutral, const ShapeData& data,
                           const InterpOptions& options)
    : neutral_(neutral), data_(data), options_(options) {
  const int K = data.num_bundles;
  HMC_CHECK(neutral.NumVertices() == data.num_vertices);
  for (int k = 0; k < K; ++k) marker_index_[data.bundle_names[k]] = k;
  centres_ = data.site_neutral;
  corners_.resize(3 * K, 3);
  corner_weights_.resize(3 * K);
  for (int k = 0; k < K; ++k) {
    const SurfacePoint& s = data.sites[k];
    for (int i = 0; i < 3; ++i) {
      corners_.row(3 * k + i) = neutral.V.row(neutral.F(s.face, i));
      corner_weights_[3 * k + i] = s.bary[i];
    }
  }
  collocation_.resize(K, K);
  ParallelFor(0, K, [&](int64_t k) {
    for (int j = 0; j < K; ++j) {
      double value = 0;
      for (int a = 0; a < 3; ++a) {
        for (int b = 0; b < 3; ++b) {
          value += corner_weights_[3 * k + a] * corner_weights_[3 * j + b] *
                   (corners_.row(3 * k + a) - corners_.row(3 * j + b)).norm();
        }
      }
      collocation_(k, j) = value;
    }
  });
  representative_.resize(K);
  std::vector<int> all;
  for (int k = 0; k < K; ++k) {
    representative_[k] = k;
    for (int j : all) {
      if ((centres_.row(j) - centres_.row(k)).norm() <= options_.merge_mm) {
        representative_[k] = j;
        break;
      }
    }
    if (representative_[k] == k) all.push_back(k);
  }
  num_sites_ = static_cast<int>(all.size());
  full_lu_.compute(System(collocation_, centres_, all));
}

bool InterpSolver::InterpolateDisplacements(const std::vector<Vec3>& disp,
                                           const std::vector<char>& observed,
                                           MatX3d* field,
                                           std::string* reason) const {
  const int K = data_.num_bundles, V = data_.num_vertices;
  HMC_CHECK(static_cast<int>(disp.size()) == K);
  HMC_CHECK(static_cast<int>(observed.size()) == K);
  // Bundles sharing a site (within merge_mm on the neutral) give one
  // constraint, their mean displacement; without the merge the system would
  // be singular or ill-conditioned.
  std::vector<int> ids;          // one observed bundle per group
  std::vector<Vec3> group_disp;  // the group's summed displacements
  std::vector<int> group_size;
  std::vector<int> slot(K, -1);  // per representative: index into ids
  for (int k = 0; k < K; ++k) {
    if (!observed[k]) continue;
    const int r = representative_[k];
    if (slot[r] < 0) {
      slot[r] = static_cast<int>(ids.size());
      ids.push_back(k);
      group_disp.push_back(disp[k]);
      group_size.push_back(1);
    } else {
      group_disp[slot[r]] += disp[k];
      ++group_size[slot[r]];
    }
  }
  const int n = static_cast<int>(ids.size());
  // The affine term needs four sites that are not coplanar.
  if (n < 4) {
    *reason = fmt::format("only {} distinct bundle sites observed (need 4)", n);
    return false;
  }
  Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(n + 4, 3);
  for (int a = 0; a < n; ++a) {
    rhs.row(a) = group_disp[a].transpose() / group_size[a];
  }
  const Eigen::MatrixXd system = System(collocation_, centres_, ids);
  const Eigen::MatrixXd coeffs = n == num_sites_
                                     ? full_lu_.solve(rhs).eval()
                                     : system.partialPivLu().solve(rhs).eval();
  if (!coeffs.allFinite() ||
      (system * coeffs - rhs).norm() > 1e-6 * (1 + rhs.norm())) {
    *reason =
        "the observed bundles do not determine the interpolation "
        "(coplanar sites)";
    return false;
  }
  const Eigen::Matrix<double, 4, 3> affine = coeffs.bottomRows(4);
  field->resize(V, 3);
  ParallelFor(
      0, V,
      [&](int64_t v) {
        const Vec3 x = neutral_.V.row(v).transpose();
        Vec3 d =
            affine.row(0).transpose() + affine.bottomRows(3).transpose() * x;
        for (int a = 0; a < n; ++a) {
          const int j = ids[a];
          double psi = 0;
          for (int b = 0; b < 3; ++b) {
            psi += corner_weights_[3 * j + b] *
                   (x - corners_.row(3 * j + b).transpose()).norm();
          }
          d += psi * coeffs.row(a).transpose();
        }
        field->row(v) = d.transpose();
      },
      64);
  return true;
}

FrameSolve InterpSolver::SolveFrame(const BundleFrame& bundles,
                                    const JawPose& jaw, MatX3d* mesh) const {
  const int K = data_.num_bundles;
  FrameSolve f;
  const std::vector<char> observed =
      BeginFrame(bundles, jaw, marker_index_, K, &f);
  std::vector<Vec3> disp(K, Vec3::Zero());
  int num_observed = 0;
  for (int k = 0; k < K; ++k) {
    if (!observed[k]) continue;
    ++num_observed;
    f.bundles[k].status = BundleSolve::Status::kInside;
    disp[k] = UnskinBundle(data_, k, jaw, f.bundles[k].observed) -
              centres_.row(k).transpose();
  }
  const int needed = BundlesNeeded(options_.min_bundle_fraction, K);
  auto fail = [&](const std::string& reason) {
    for (BundleSolve& b : f.bundles) b.status = BundleSolve::Status::kUnused;
    f.reason = reason;
    return f;
  };
  if (num_observed < needed) {
    return fail(fmt::format("only {} of {} bundles observed (need {})",
                            num_observed, K, needed));
  }
  MatX3d field;
  std::string reason;
  if (!InterpolateDisplacements(disp, observed, &field, &reason)) {
    return fail(reason);
  }
  f.ok = true;
  if (!mesh) return f;
  const MatX3d out = neutral_.V + field;
  *mesh = data_.jaw_rig ? Skin(*data_.jaw_rig, jaw, out) : out;
  SetResiduals(data_.sites, neutral_.F, *mesh, &f);
  return f;
}

SolveResult InterpSolver::SolveSequence(
    const std::vector<BundleFrame>& frames, const std::vector<JawPose>& jaw,
    const std::vector<std::string>& frame_errors) const {
  return RunBaselineSequence(
      data_, neutral_, frames, jaw, frame_errors,
      [&](int, const BundleFrame& b, const JawPose& pose, MatX3d* mesh) {
        return SolveFrame(b, pose, mesh);
      },
      "interp");
}

}  // namespace hmc
