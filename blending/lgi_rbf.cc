#include "blending/lgi_rbf.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <map>

#include "blending/kernel_smoother.h"
#include "core/error.h"
#include "core/jaw.h"
#include "core/logging.h"
#include "core/parallel.h"
#include "indexing/shape_data.h"

namespace hmc {

void LgiRbfOptions::Register(OptionFields* fields) {
  fields->SetGroup("lgi_rbf");
  fields->Add("sigma_mm", &sigma_mm,
              "Gaussian width (mm); 0: sigma_scale times the median distance "
              "of a bundle site to its nearest site on the neutral")
      .AtLeast(0);
  fields->Add("sigma_scale", &sigma_scale,
              "automatic Gaussian width, in nearest-site distances")
      .Above(0);
  fields->Add("ridge", &ridge,
              "Tikhonov term added to the kernel matrix's unit diagonal")
      .AtLeast(0);
  fields->Add("cutoff", &cutoff,
              "kernel values below this are dropped (sparse evaluation)")
      .Above(0).Below(1);
  fields->Add("correct", &correct,
              "smoothly correct the RBF result so it passes through the "
              "bundles (false: plain RBF, for comparison)");
  fields->SetGroup("");
}

bool LgiRbfOptions::Check() const {
  CHECK_OPTION_LIMITS();
  return true;
}

namespace {

double Gaussian(double squared_distance, double sigma) {
  return std::exp(-squared_distance / (2 * sigma * sigma));
}

}  // namespace

LgiRbfSolver::LgiRbfSolver(const TriMesh& neutral, const ShapeData& data,
                           const LgiSolver& lgi, const LgiRbfOptions& options,
                           const InterpOptions& interp_options)
    : neutral_(neutral),
      data_(data),
      lgi_(lgi),
      options_(options),
      correction_(neutral, data, interp_options) {
  const int K = data.num_bundles, V = data.num_vertices;
  HMC_CHECK(neutral.NumVertices() == V);
  const MatX3d& sites = data.site_neutral;
  sigma_ = options.sigma_mm;
  if (sigma_ <= 0) {
    // Scale-free default: the kernel spans about one marker spacing, so the
    // weight field neither collapses to spikes at the sites nor smears a
    // bundle's expression across distant ones.
    sigma_ = options.sigma_scale * MedianNearestSiteDistance(sites, 10.0);
  }
  kernel_.resize(K, K);
  for (int k = 0; k < K; ++k) {
    for (int j = 0; j < K; ++j) {
      kernel_(k, j) =
          Gaussian((sites.row(k) - sites.row(j)).squaredNorm(), sigma_);
    }
    kernel_(k, k) += options.ridge;
  }
  full_llt_.compute(kernel_);
  HMC_CHECK_MSG(full_llt_.info() == Eigen::Success,
                "lgi-rbf: the Gaussian kernel matrix is not positive "
                "definite (coincident bundle sites and ridge 0?)");
  // Per vertex, the kernel to every site within the cutoff radius.
  vertex_kernel_ =
      GaussianKernelMatrix(neutral.V, sites, sigma_, options.cutoff);
}

bool LgiRbfSolver::Blend(FrameSolve* frame, MatX3d* mesh) const {
  const int K = data_.num_bundles, V = data_.num_vertices;
  const int N = data_.num_shapes;
  HMC_CHECK(static_cast<int>(frame->bundles.size()) == K);
  // The shapes any bundle uses: the only columns of the weight field.
  std::map<int, int> column;
  std::vector<int> used;  // bundles with a choice
  for (int k = 0; k < K; ++k) {
    const BundleSolve& b = frame->bundles[k];
    if (b.status == BundleSolve::Status::kUnused) continue;
    used.push_back(k);
    for (const auto& [n, w] : b.weights) {
      HMC_CHECK(n >= 0 && n < N);
      column.emplace(n, 0);
    }
  }
  std::vector<int> shapes;
  for (auto& [n, c] : column) {
    c = static_cast<int>(shapes.size());
    shapes.push_back(n);
  }
  const int M = static_cast<int>(shapes.size());
  const int U = static_cast<int>(used.size());
  Eigen::MatrixXd coeffs = Eigen::MatrixXd::Zero(K, M);  // A
  if (M > 0 && U > 0) {
    Eigen::MatrixXd W = Eigen::MatrixXd::Zero(U, M);
    for (int a = 0; a < U; ++a) {
      for (const auto& [n, w] : frame->bundles[used[a]].weights) {
        W(a, column.at(n)) = w;
      }
    }
    if (U == K) {
      coeffs = full_llt_.solve(W);
    } else {
      Eigen::MatrixXd sub(U, U);
      for (int a = 0; a < U; ++a) {
        for (int b = 0; b < U; ++b) sub(a, b) = kernel_(used[a], used[b]);
      }
      const Eigen::MatrixXd A = sub.llt().solve(W);
      for (int a = 0; a < U; ++a) coeffs.row(used[a]) = A.row(a);
    }
  }
  // y*(v) = x0(v) + sum_n w_n(v) b*_n(v), w(v) = sum_k phi_k(v) A_k.
  MatX3d unskinned(V, 3);
  ParallelFor(
      0, V,
      [&](int64_t v) {
        Eigen::VectorXd w = Eigen::VectorXd::Zero(M);
        for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(
                 vertex_kernel_, v);
             it; ++it) {
          w += it.value() * coeffs.row(it.col()).transpose();
        }
        Vec3 x = neutral_.V.row(v).transpose();
        for (int m = 0; m < M; ++m) {
          const float* bn = data_.Displacement(static_cast<int>(v), shapes[m]);
          if (bn) x += w[m] * Vec3(bn[0], bn[1], bn[2]);
        }
        unskinned.row(v) = x.transpose();
      },
      64);
  if (options_.correct) {
    std::vector<Vec3> disp(K, Vec3::Zero());
    std::vector<char> observed(K, 0);
    for (int k = 0; k < K; ++k) {
      const BundleSolve& b = frame->bundles[k];
      if (!b.Measured()) continue;
      observed[k] = 1;
      disp[k] = UnskinBundle(data_, k, frame->jaw, b.observed) -
                EvaluateSurfacePoint(data_.sites[k], neutral_.F, unskinned);
    }
    MatX3d field;
    std::string reason;
    if (!correction_.InterpolateDisplacements(disp, observed, &field,
                                              &reason)) {
      frame->ok = false;
      frame->reason = "lgi-rbf correction: " + reason;
      return false;
    }
    unskinned += field;
  }
  *mesh = data_.jaw_rig ? Skin(*data_.jaw_rig, frame->jaw, unskinned)
                        : unskinned;
  SetResiduals(data_.sites, neutral_.F, *mesh, frame);
  return true;
}

SolveResult LgiRbfSolver::SolveSequence(
    const std::vector<BundleFrame>& frames, const std::vector<JawPose>& jaw,
    const std::vector<std::string>& frame_errors) const {
  // The lgi solve makes the per-bundle choices (with its temporal
  // preference and smoothing) and the bad-frame decisions; its own
  // natural-neighbour meshes are replaced below.
  return SolveFromLgi(lgi_.SolveSequence(frames, jaw, frame_errors));
}

SolveResult LgiRbfSolver::SolveFromLgi(SolveResult lgi_result) const {
  SolveResult result = std::move(lgi_result);
  const int F = static_cast<int>(result.frames.size());
  Progress progress("lgi-rbf blend", F);
  for (int f = 0; f < F; ++f) {
    FrameSolve& fs = result.frames[f];
    MatX3d mesh;
    if (fs.ok && Blend(&fs, &mesh)) result.meshes[f] = std::move(mesh);
    progress.Advance();
  }
  progress.Finish();
  // Bad frames (lgi's, and those whose correction failed) repeat the
  // previous good mesh of this method.
  FillBadMeshes(neutral_, data_.jaw_rig ? &*data_.jaw_rig : nullptr, &result);
  result.report.values = {{"gaussian_sigma_mm", sigma_mm()}};
  result.report.brief = fmt::format("Gaussian sigma {:.3f} mm", sigma_mm());
  return result;
}

}  // namespace hmc
