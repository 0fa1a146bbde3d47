// Steps 4-6 of the robust solve (blending/robust_solver.h): the
// natural-neighbour blend of each bundle's weights, plus step 5's
// correction, skinned with the frame's jaw pose; bad frames filled.
#include <optional>
#include <utility>
#include <vector>

#include <Eigen/SparseCore>

#include "blending/robust_solver.h"
#include "blending/robust_solver_state.h"
#include "core/error.h"
#include "core/jaw.h"
#include "core/logging.h"
#include "core/parallel.h"

namespace hmc {

Vec3 RobustSolver::BlendVertex(const Work& work, const FrameSolve& frame,
                               int v) const {
  Vec3 x = neutral_.V.row(v).transpose();
  auto add = [&](const std::vector<std::pair<int, double>>& weights,
                 double scale) {
    for (const auto& [n, w] : weights) {
      const float* bn = data_.Displacement(v, n);
      if (!bn) continue;
      const double c = scale * w;
      x[0] += c * bn[0];
      x[1] += c * bn[1];
      x[2] += c * bn[2];
    }
  };
  double global_share = 0.0;
  for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(
           nn_.weights, v);
       it; ++it) {
    // Its share of the frame's global answer, and its own weights.
    const BundleSolve& b = frame.bundles[it.col()];
    global_share += it.value() * b.global_share;
    add(b.weights, it.value());
  }
  if (global_share > 0) add(work.global_nonzero, global_share);
  return x;
}

std::vector<MatX3d> RobustSolver::BlendBatch(
    const std::vector<const Work*>& work,
    const std::vector<const FrameSolve*>& frames,
    const Eigen::SparseMatrix<double, Eigen::RowMajor>* kernel) const {
  constexpr int B = kBlendBatch;
  const int count = static_cast<int>(work.size());
  HMC_CHECK(count <= B && work.size() == frames.size());
  const int N = data_.num_shapes, K = data_.num_bundles;
  // The kernel's coefficients and the interpolated offsets, per bundle,
  // with the frame innermost: [k][c][frame] (0 in frames without them;
  // empty when no frame of the batch has any).
  auto per_bundle = [&](auto&& get) {
    std::vector<float> out(static_cast<size_t>(K) * 3 * B, 0.0f);
    bool any = false;
    for (int i = 0; i < count; ++i) {
      for (int k = 0; k < K; ++k) {
        for (int c = 0; c < 3; ++c) {
          const double value = get(*work[i], k, c);
          out[(k * 3 + c) * B + i] = static_cast<float>(value);
          any = any || value != 0.0;
        }
      }
    }
    if (!any) out.clear();
    return out;
  };
  const std::vector<float> a =
      kernel ? per_bundle([](const Work& w, int k, int c) {
        return w.alpha.size() > 0 ? w.alpha(k, c) : 0.0;
      })
             : std::vector<float>();
  const std::vector<float> o = per_bundle([](const Work& w, int k, int c) {
    return w.offset.empty() ? 0.0 : w.offset[k][c];
  });
  // The global weights, G[n][frame] (0 in frames without a global fit).
  std::vector<float> G(static_cast<size_t>(N) * B, 0.0f);
  for (int i = 0; i < count; ++i) {
    for (const auto& [n, w] : work[i]->global_nonzero) {
      G[static_cast<size_t>(n) * B + i] = static_cast<float>(w);
    }
  }
  const JawRig* rig = data_.jaw_rig ? &*data_.jaw_rig : nullptr;
  std::vector<Rigid3> jaw(count);
  for (int i = 0; rig && i < count; ++i) jaw[i] = rig->Transform(frames[i]->jaw);
  // Constructed in place: copies of one prototype would memmove 1.2 MB per
  // frame into fresh pages on the calling thread alone.
  std::vector<MatX3d> out;
  out.reserve(count);
  for (int i = 0; i < count; ++i) out.emplace_back(data_.num_vertices, 3);
  ParallelFor(
      0, data_.num_vertices,
      [&](int64_t v) {
        // In single precision, as the displacements are stored (the sums'
        // rounding, ~1e-6 mm, is far below the verification's 1e-3 mm).
        // A vertex no shape moves (44 % of the default actor's) needs no
        // weights.
        float acc[3][B] = {};
        // The shapes that move v and their displacements (the others add 0).
        const int first = data_.vertex_shape_start[v];
        const int last = data_.vertex_shape_start[v + 1];
        const int* moving = data_.vertex_shapes.data();
        const float* d = data_.vertex_shape_displacement.data();
        if (first < last) {
          // The local choices, sum_k lambda_k(v) sum_n u_kn d_n(v), and the
          // natural-neighbour weight (share) of the bundles that took the
          // global fit.
          float share[B] = {};
          for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(
                   nn_.weights, v);
               it; ++it) {
            for (int i = 0; i < count; ++i) {
              // Its share of the frame's global answer, and its own weights.
              const BundleSolve& b = frames[i]->bundles[it.col()];
              if (b.global_share != 0.0) {
                share[i] += static_cast<float>(it.value() * b.global_share);
              }
              for (const auto& [n, u] : b.weights) {
                const float* dn = data_.Displacement(static_cast<int>(v), n);
                if (!dn) continue;
                const float c = static_cast<float>(it.value() * u);
                acc[0][i] += c * dn[0];
                acc[1][i] += c * dn[1];
                acc[2][i] += c * dn[2];
              }
            }
          }
          // share * G over the shapes that move v, frame innermost.
          for (int j = first; j < last; ++j) {
            const int n = moving[j];
            const float d0 = d[3 * j], d1 = d[3 * j + 1], d2 = d[3 * j + 2];
            const float* gn = &G[static_cast<size_t>(n) * B];
            for (int i = 0; i < B; ++i) {
              const float w = share[i] * gn[i];
              acc[0][i] += d0 * w;
              acc[1][i] += d1 * w;
              acc[2][i] += d2 * w;
            }
          }
        }
        // sum_k m(v, k) c_k for per-bundle coefficients c: the kernel's
        // correction and the interpolated offsets.
        auto add_row = [&](const Eigen::SparseMatrix<double, Eigen::RowMajor>& m,
                           const std::vector<float>& coefficients) {
          for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(
                   m, v);
               it; ++it) {
            const float mv = static_cast<float>(it.value());
            const float* ck =
                &coefficients[static_cast<size_t>(it.col()) * 3 * B];
            for (int c = 0; c < 3; ++c) {
              for (int i = 0; i < B; ++i) acc[c][i] += mv * ck[c * B + i];
            }
          }
        };
        if (!a.empty()) add_row(*kernel, a);
        if (!o.empty()) add_row(nn_.weights, o);
        for (int i = 0; i < count; ++i) {
          Vec3 x;
          for (int c = 0; c < 3; ++c) x[c] = neutral_.V(v, c) + acc[c][i];
          if (rig) x = SkinPoint(jaw[i], x, rig->weights[v]);
          out[i].row(v) = x.transpose();
        }
      },
      256);
  return out;
}

// Steps 4-6, kBlendBatch good frames at a time; bad frames repeat the
// previous good mesh. With a sink the meshes go to it batch by batch, so a
// long shot holds kBlendBatch meshes, not all of them.
void RobustSolver::BlendFrames(Sequence* seq, const MeshSink* sink) const {
  const int F = static_cast<int>(seq->work.size());
  std::vector<Work>& work = seq->work;
  SolveResult& result = seq->result;
  const int width_index = seq->width_index;
  const JawRig* rig = data_.jaw_rig ? &*data_.jaw_rig : nullptr;
  Progress progress("robust: blend", F);
  SolveSummary& s = result.summary;
  s.frames = F;
  const auto* kernel =
      width_index >= 0 ? &vertex_kernel_.at(width_index) : nullptr;
  std::optional<MeshStream> stream;
  if (sink) stream.emplace(neutral_, rig, &result, *sink);
  if (sink) result.meshes.clear();
  for (int begin = 0; begin < F;) {
    std::vector<const Work*> batch_work;
    std::vector<const FrameSolve*> batch_frames;
    int end = begin;
    for (; end < F && batch_work.size() < kBlendBatch; ++end) {
      const Work& wk = work[end];
      if (!wk.ok) continue;
      batch_work.push_back(&wk);
      batch_frames.push_back(&result.frames[end]);
    }
    std::vector<MatX3d> blended = BlendBatch(batch_work, batch_frames, kernel);
    for (int f = begin, i = 0; f < end; ++f) {
      FrameSolve& fs = result.frames[f];
      Work& wk = work[f];
      const bool ok = wk.ok;
      if (ok) {
        MatX3d& mesh = blended[i++];
        SetResiduals(data_.sites, neutral_.F, mesh, &fs);
        if (!stream) result.meshes[f] = std::move(mesh);
      }
      // The frame's working state is done with: released as the meshes
      // come, so a long shot holds its meshes and records, not both.
      wk = Work();
      s.Count(fs);
      if (stream) {
        if (ok) {
          stream->Good(f, std::move(blended[i - 1]));
        } else {
          stream->Bad(f);
        }
      }
      progress.Advance();
    }
    begin = end;
  }
  if (stream) {
    stream->Finish();
  } else {
    FillBadMeshes(neutral_, rig, &result);
  }
}

}  // namespace hmc
