// The per-frame solve of local geometric indexing (paper, "Local Geometric
// Indexing", "Choosing Tetrahedra", "Jaw Articulation", "Temporal
// Smoothing"; docs/ARCHITECTURE.md, "Method steps", 4-9):
//   1. unskin each observed bundle with the frame's jaw pose;
//   2. query its index: every simplex containing it, else the closest ones;
//   3. choose among the candidates by the neighbour criterion (how close the
//      candidate's blended shape puts the natural-neighbour bundles' surface
//      points to where they were observed), within a slack preferring the
//      simplices that share shapes with the previous frame's choice;
//   4. fill missing bundles from their neighbours;
//   5. optionally average each bundle's shape weights over a centred window;
//   6. blend x*(v) = x0(v) + sum_k lambda_k(v) sum_n w_{k,n} b*_n(v) and skin
//      with the frame's jaw pose (linear blend skinning).
#pragma once

#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "blending/frame_solve.h"
#include "blending/natural_neighbour.h"
#include "core/frame_data.h"
#include "core/options.h"
#include "indexing/index_options.h"
#include "indexing/shape_data.h"
#include "indexing/shape_index.h"

namespace hmc {

struct SolveOptions {
  double outside_slack_mm = 0.1;  // outside the data: simplices whose closest
                                  // point is within this of the closest one
                                  // compete by the neighbour criterion plus
                                  // their own squared distance (mm)
  double temporal_preference = 0.0;  // animation: while the previous
                                      // frame's simplex still contains the
                                      // bundle, candidates whose neighbour
                                      // cost is within this fraction of the
                                      // best compete by the number of shapes
                                      // shared with that choice (0 = off)
  double tie_mm2 = 1e-10;  // candidates whose neighbour costs differ by at
                           // most this are tied (mm^2); ties go to the one
                           // agreeing most with the neighbours' choices,
                           // then to the least motion over the region
  int smooth_window = 0;  // frames of the centred moving average of the
                          // shape weights (0 or 1 = off; even is rounded up)
  double min_bundle_fraction = 0.5;  // a frame with fewer observed bundles
                                     // than this fraction of the markers is
                                     // bad: flagged, previous good mesh kept

  void Register(OptionFields* fields);
  bool Check() const;
};

class LgiSolver {
 public:
  // All referenced data must outlive the solver. neutral: the actor's
  // neutral mesh (V x 3 positions in mm, triangles).
  LgiSolver(const TriMesh& neutral, const ShapeData& data,
            const ShapeIndex& index, const NaturalNeighbourWeights& nn,
            const IndexOptions& index_options, const SolveOptions& options);

  // Steps 1-4 for one frame. previous: the previous frame's solve (its
  // choices steer the temporal preference), or nullptr.
  FrameSolve SolveFrame(const BundleFrame& bundles, const JawPose& jaw,
                        const FrameSolve* previous) const;

  // Step 6 for one frame's weights; also fills each bundle's residual.
  MatX3d Blend(FrameSolve* frame) const;

  // Steps 1-6 over a sequence. jaw: one pose per frame (empty: zero pose).
  // frame_errors: empty, or one entry per frame; a non-empty entry marks the
  // frame bad with that reason (e.g. no jaw pose). Bad frames repeat the
  // previous good mesh (the jaw-skinned neutral before the first good one).
  SolveResult SolveSequence(
      const std::vector<BundleFrame>& frames, const std::vector<JawPose>& jaw,
      const std::vector<std::string>& frame_errors = {}) const;

  // Centred moving average of each bundle's weights over `window` frames
  // (bad frames excluded); relative to the jaw-skinned neutral, since the
  // blend skins each frame with its own pose afterwards.
  static void SmoothWeights(int window, std::vector<FrameSolve>* frames);

  // The unskinned position candidate `candidate` of bundle k's index
  // predicts for bundle j's surface point: x0(s_j) + sum_i w_i b*_i(s_j).
  Vec3 Predict(int k, const IndexCandidate& candidate, int j) const;

  int NumBundles() const { return data_.num_bundles; }
  // Bundle k's natural neighbours (without k), as the criterion uses them.
  const std::vector<int>& Neighbours(int k) const { return neighbours_[k]; }

 private:
  // Sets out's choice (simplex, corner shapes, weights, cost). A candidate
  // sitting on one cloud point may stand for another shape the point
  // represents: `representative` (>= -1; -1 the neutral) then replaces the
  // point's own shape; kNoRepresentative keeps the corners' shapes.
  static constexpr int kNoRepresentative = -2;
  void Assign(int k, const IndexCandidate& candidate, double cost,
              BundleSolve* out, int representative = kNoRepresentative) const;

  // The pieces of SolveFrame (steps 2-4), in order.
  // Step 2: the index's candidates for bundle k at its unskinned position,
  // plus the cloud points within the pruning thresholds.
  IndexQuery GatherCandidates(int k, const Vec3& unskinned) const;
  // Step 3's neighbour criterion for each candidate (mm^2, plus its squared
  // projection distance), with the shape a point candidate stands for
  // (kNoRepresentative: its own); returns the best cost. *tied: per
  // candidate, the other shapes it stands for (kNoRepresentative: its own)
  // whose cost ties with that one's, for BreakTies.
  double NeighbourCosts(int k, const IndexQuery& q,
                        const std::vector<char>& observed,
                        const std::vector<Vec3>& unskinned,
                        std::vector<double>* costs,
                        std::vector<int>* representatives,
                        std::vector<std::vector<int>>* tied) const;
  // Step 3's choice within the slack: the candidate sharing the most shapes
  // with the previous frame's choice (temporal preference), then the
  // cheapest; *shared_shapes: per candidate, the shapes shared.
  int TemporalChoice(int k, const IndexQuery& q,
                     const std::vector<double>& cost, double best,
                     const FrameSolve* previous,
                     std::vector<int>* shared_shapes) const;
  // Per bundle, the candidates whose cost ties with the best one; a
  // candidate on a point appears once per shape it stands for that ties
  // (the bundle is tied, and votes for no shape, only when its candidates'
  // own choices differ).
  struct TieGroups {
    explicit TieGroups(int num_bundles)
        : candidates(num_bundles), cost(num_bundles),
          representative(num_bundles), shared(num_bundles),
          primary(num_bundles),
          chosen_representative(num_bundles, kNoRepresentative) {}
    std::vector<std::vector<IndexCandidate>> candidates;
    std::vector<std::vector<double>> cost;
    std::vector<std::vector<int>> representative;
    std::vector<std::vector<int>> shared;
    // Whether the entry is its candidate's own choice of representative
    // (the others: shapes it also stands for that tie).
    std::vector<std::vector<char>> primary;
    std::vector<int> chosen_representative;  // of the first choice
  };
  // Step 3's ties: settled by the frame's consensus, then least motion.
  void BreakTies(const TieGroups& tie, FrameSolve* frame) const;
  // Step 4: missing bundles take their neighbours' weights.
  void FillMissing(FrameSolve* frame) const;

  const TriMesh& neutral_;
  const ShapeData& data_;
  const ShapeIndex& index_;
  const NaturalNeighbourWeights& nn_;
  IndexOptions index_options_;
  SolveOptions options_;
  std::unordered_map<std::string, int> marker_index_;
  // Per bundle k, for the neighbour criterion as a quadratic form in the
  // candidate's weights: neighbours_[k] (its natural neighbours, without k),
  // site_disp_[k] (P x 3J: cloud point i's unskinned displacement at each
  // neighbour's surface point) and gram_[k] = site_disp_ site_disp_^T (P x P).
  std::vector<std::vector<int>> neighbours_;
  std::vector<Eigen::MatrixXd> site_disp_;
  std::vector<Eigen::MatrixXd> gram_;
  // Per bundle, the other shapes a cloud point stands for (merged into it or
  // pruned into the neutral: they agree with the point's shape over the
  // bundle's region, not necessarily at the neighbours' sites). A candidate
  // on that point is scored with whichever of them best explains the
  // neighbours and its own surface point. alt_point_[k][a] (ascending),
  // alt_shape_[k][a], alt_disp_[k].row(a) (3J, as site_disp_),
  // alt_site_[k][a] (the shape's unskinned position of bundle k's point).
  std::vector<std::vector<int>> alt_point_, alt_shape_;
  std::vector<Eigen::MatrixXd> alt_disp_;
  std::vector<std::vector<Vec3>> alt_site_;
  // Per bundle and cloud point: its shape's motion over the bundle's region,
  // sum_v lambda_k(v) |b*_n(v)| (mm), the last tie-breaker.
  std::vector<std::vector<double>> point_motion_;
};

}  // namespace hmc
