#include "eval/eval_metrics.h"

#include <fmt/format.h>

#include <limits>
#include <map>

#include "core/error.h"
#include "core/error_stats.h"
#include "core/parallel.h"

namespace hmc {

SequenceEvaluator::SequenceEvaluator(const Actor& actor,
                                     const MeshMetricsOptions& options)
    : actor_(actor), options_(options) {
  for (const Marker& m : actor.markers) sites_.push_back(m.point);
  face_ = FaceRegionMask(actor.neutral, sites_, options.face_radius_mm);
  laplacian_ = UniformLaplacian(actor.neutral.F, actor.NumVertices());
}

SequenceMetrics SequenceEvaluator::Evaluate(
    const std::vector<MatX3d>& truth, const std::vector<MatX3d>& recon,
    const std::vector<int>& numbers,
    const std::vector<BundleFrame>* bundles) const {
  const TriMesh& neutral = actor_.neutral;
  const int V = neutral.NumVertices();
  const int F = static_cast<int>(truth.size());
  const int K = static_cast<int>(sites_.size());
  if (recon.size() != truth.size() || numbers.size() != truth.size()) {
    throw InputError(fmt::format(
        "evaluation: {} truth frames, {} reconstructed, {} frame numbers",
        truth.size(), recon.size(), numbers.size()));
  }
  for (int f = 0; f < F; ++f) {
    if (truth[f].rows() != V || recon[f].rows() != V) {
      throw InputError(fmt::format(
          "evaluation: frame {} has {} truth and {} reconstructed vertices, "
          "the actor has {}",
          numbers[f], truth[f].rows(), recon[f].rows(), V));
    }
  }
  std::map<int, const BundleFrame*> bundles_by_frame;
  if (bundles) {
    for (const BundleFrame& b : *bundles) bundles_by_frame[b.frame] = &b;
  }

  SequenceMetrics out;
  out.frames = F;
  out.vertices = V;
  for (uint8_t m : face_) out.face_vertices += m;
  out.per_frame.resize(F);
  // Per frame: the values that are pooled afterwards, in frame order.
  struct Pools {
    std::vector<double> face, all, bundle, detail_face;
    Eigen::VectorXd err, detail;
  };
  std::vector<Pools> pools(F);
  ParallelFor(0, F, [&](int64_t f) {
    const MatX3d& t = truth[f];
    const MatX3d& r = recon[f];
    FrameMetrics& e = out.per_frame[f];
    Pools& p = pools[f];
    e.frame = numbers[f];
    p.err = VertexErrors(t, r);
    p.face = Select(p.err, face_);
    p.all = Select(p.err, {});
    std::vector<double> scratch = p.face;
    e.face = ComputeErrorStats(&scratch);
    scratch = p.all;
    e.all = ComputeErrorStats(&scratch);
    p.detail = DetailErrors(laplacian_, t, r);
    p.detail_face = Select(p.detail, face_);
    e.detail_face = MeanOf(p.detail_face);
    e.detail_all = p.detail.mean();
    // Bundle targets: the truth's surface points, or the given bundles.
    MatX3d targets(K, 3);
    if (!bundles) {
      for (int k = 0; k < K; ++k) {
        targets.row(k) =
            EvaluateSurfacePoint(sites_[k], neutral.F, t).transpose();
      }
    } else {
      targets.setConstant(std::numeric_limits<double>::quiet_NaN());
      const auto it = bundles_by_frame.find(e.frame);
      if (it != bundles_by_frame.end()) {
        for (int k = 0; k < K; ++k) {
          const auto b = it->second->bundles.find(actor_.markers[k].name);
          if (b != it->second->bundles.end()) {
            targets.row(k) = b->second.transpose();
          }
        }
      }
    }
    p.bundle = BundleResiduals(neutral.F, sites_, r, targets);
    scratch = p.bundle;
    e.bundle = ComputeErrorStats(&scratch);
  });

  std::vector<double> pool_face, pool_all, pool_bundle, pool_detail_face;
  pool_face.reserve(static_cast<size_t>(out.face_vertices) * F);
  pool_all.reserve(static_cast<size_t>(V) * F);
  double detail_all_sum = 0;
  out.mean_vertex_error = Eigen::VectorXd::Zero(V);
  for (Pools& p : pools) {
    pool_face.insert(pool_face.end(), p.face.begin(), p.face.end());
    pool_all.insert(pool_all.end(), p.all.begin(), p.all.end());
    pool_bundle.insert(pool_bundle.end(), p.bundle.begin(), p.bundle.end());
    pool_detail_face.insert(pool_detail_face.end(), p.detail_face.begin(),
                            p.detail_face.end());
    detail_all_sum += p.detail.sum();
    out.mean_vertex_error += p.err;
    p = Pools();
  }
  if (F > 0) out.mean_vertex_error /= F;
  out.face = ComputeErrorStats(&pool_face);
  out.all = ComputeErrorStats(&pool_all);
  out.bundle = ComputeErrorStats(&pool_bundle);
  out.detail_face = MeanOf(pool_detail_face);
  out.detail_all =
      F > 0 && V > 0 ? detail_all_sum / (static_cast<double>(F) * V) : 0.0;
  std::vector<char> face_mask(face_.begin(), face_.end());
  out.flicker_face = ComputeFlicker(truth, recon, face_mask, {});
  out.flicker_all = ComputeFlicker(truth, recon, {}, {});
  return out;
}

nlohmann::json StatsJson(const ErrorStats& s) {
  return {{"count", s.count},
          {"mean_mm", s.mean},
          {"rms_mm", s.rms},
          {"p95_mm", s.p95},
          {"max_mm", s.max}};
}

nlohmann::json PooledMetricsJson(const SequenceMetrics& m) {
  return {{"face", StatsJson(m.face)},
          {"all", StatsJson(m.all)},
          {"bundle", StatsJson(m.bundle)},
          {"detail_face_mm", m.detail_face},
          {"detail_all_mm", m.detail_all},
          {"flicker_face_mm_per_frame2", m.flicker_face.mean},
          {"flicker_all_mm_per_frame2", m.flicker_all.mean},
          {"flicker_frames_used", m.flicker_all.frames_used}};
}

}  // namespace hmc
