// The reconstruction metrics of a whole sequence, shared by `hmc eval` and
// `hmc experiment` so both report the same numbers for the same meshes:
// per frame and pooled over the frames, vertex-error statistics over the
// face region and over all vertices, the bundle residual, the detail error
// (core/mesh_metrics.h defines each) and flicker (core/flicker.h).
//
// Pooled statistics are over every (frame, vertex) pair, not means of
// per-frame statistics: the 95th percentile of all errors of the sequence.
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <cstdint>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/actor.h"
#include "core/flicker.h"
#include "core/frame_data.h"
#include "core/mesh_metrics.h"

namespace hmc {

struct FrameMetrics {
  int frame = 0;                           // frame number
  ErrorStats face, all, bundle;            // vertex and bundle errors (mm)
  double detail_face = 0, detail_all = 0;  // mean |delta_T - delta_R| (mm)
};

struct SequenceMetrics {
  int frames = 0;
  int vertices = 0;
  int face_vertices = 0;  // vertices in the face region
  std::vector<FrameMetrics> per_frame;
  ErrorStats face, all, bundle;  // pooled over frames (mm)
  double detail_face = 0, detail_all = 0;  // pooled means (mm)
  FlickerStats flicker_face, flicker_all;  // mm/frame^2
  Eigen::VectorXd mean_vertex_error;       // V: mean error per vertex (mm)
};

// Precomputes what does not depend on the frames (the face region, the
// Laplacian) once per actor, so an experiment evaluates many sequences
// cheaply.
class SequenceEvaluator {
 public:
  // actor must outlive the evaluator.
  SequenceEvaluator(const Actor& actor, const MeshMetricsOptions& options);

  // truth, recon: F matched frames, V x 3 each (mm); numbers: their F frame
  // numbers (consecutive for flicker to mean anything). bundles: nullptr to
  // measure the bundle residual against the truth's marker surface points,
  // else the observed bundles (matched by frame number and marker name;
  // markers without a row are skipped). Throws InputError when the sizes
  // do not match the actor.
  SequenceMetrics Evaluate(const std::vector<MatX3d>& truth,
                           const std::vector<MatX3d>& recon,
                           const std::vector<int>& numbers,
                           const std::vector<BundleFrame>* bundles) const;

  const std::vector<uint8_t>& face_mask() const { return face_; }

 private:
  const Actor& actor_;
  MeshMetricsOptions options_;
  std::vector<SurfacePoint> sites_;
  std::vector<uint8_t> face_;
  Eigen::SparseMatrix<double> laplacian_;
};

// The JSON of one statistic, {count, mean_mm, rms_mm, p95_mm, max_mm}, and
// of a sequence's pooled metrics (face, all, bundle, detail_*_mm,
// flicker_*): the keys of eval.json's "overall" and of each results.json row
// (docs/formats.md).
nlohmann::json StatsJson(const ErrorStats& s);
nlohmann::json PooledMetricsJson(const SequenceMetrics& m);

}  // namespace hmc
