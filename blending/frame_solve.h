// What every solver returns per frame and per sequence (the lgi solve, the
// robust default and the baselines alike: blending/solve_method.h), and the
// two steps of the sequence driver (core/frame_sequence.h) they share:
// marking the frames known to be bad, and filling every bad frame's mesh
// from the previous good one (docs/ARCHITECTURE.md, "Sequence driver").
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "core/actor.h"
#include "core/frame_data.h"
#include "core/frame_sequence.h"
#include "core/jaw.h"
#include "core/mesh.h"
#include "core/options.h"
#include "indexing/shape_data.h"

namespace hmc {

// One bundle in one frame.
struct BundleSolve {
  enum class Status { kInside, kProjected, kFilled, kUnused };
  Status status = Status::kUnused;
  Vec3 observed = Vec3::Zero();  // head space (when observed)
  double distance = 0.0;  // how far the unskinned bundle was projected (mm)
  int num_candidates = 0;
  int simplex = -1;                  // chosen simplex of its index
  std::vector<int> corner_shapes;    // its corners' shapes (-1: neutral)
  std::vector<std::pair<int, double>> weights;  // shape -> weight, sorted by
                                                // shape, neutral omitted
  // The robust solve's answers (read FrameSolve::Weights): the frame's
  // global_weights enter the bundle's answer with this factor, besides
  // `weights`: 0 for an answer of its own, 1 (weights empty) where it takes
  // the global answer (held once a frame), in between where step 3c
  // averages its answers over a take's frames.
  double global_share = 0.0;
  double cost = 0.0;         // neighbour criterion of the choice (mm^2)
  double residual = 0.0;     // |output surface at s_k - observed| (mm)

  // Observed in its frame and solved from its own position (inside its
  // index or projected onto it), as against filled or unused.
  bool Measured() const {
    return status == Status::kInside || status == Status::kProjected;
  }
};

struct FrameSolve {
  int frame = 0;
  bool ok = false;
  std::string reason;  // why a bad frame was skipped
  JawPose jaw;
  std::vector<BundleSolve> bundles;  // K, in marker order
  int unknown_markers = 0;           // names not in the actor (ignored)
  // The frame's global answer, for the bundles with a global_share (one
  // copy a frame: a long shot holds every frame's record).
  std::vector<std::pair<int, double>> global_weights;

  // Bundle k's weights (shape -> weight, sorted by shape), wherever and
  // however they are held.
  std::vector<std::pair<int, double>> Weights(int k) const;
};

// How every solver (lgi and the baselines) starts a frame: a FrameSolve
// with one BundleSolve per marker, the observed position of each bundle
// named in `bundles` (marker_index: name -> marker), unknown names counted.
// Returns K flags: which markers were observed.
std::vector<char> BeginFrame(
    const BundleFrame& bundles, const JawPose& jaw,
    const std::unordered_map<std::string, int>& marker_index, int num_bundles,
    FrameSolve* frame);

// Sets each measured bundle's residual: |x(s_k) - observed| on the frame's
// output `mesh` (V x 3), s_k = sites[k] on the triangles F.
void SetResiduals(const std::vector<SurfacePoint>& sites, const MatX3i& F,
                  const MatX3d& mesh, FrameSolve* frame);

// Fewest observed bundles a frame needs: ceil(min_fraction * K), at least 1.
int BundlesNeeded(double min_fraction, int num_bundles);

struct SolveSummary {
  int frames = 0;
  int bad_frames = 0;
  int64_t bundles_inside = 0;
  int64_t bundles_projected = 0;
  int64_t bundles_filled = 0;
  double max_projection = 0.0;  // mm
  // Adds the frame's bundles to the counts by status.
  void Count(const FrameSolve& frame);
  std::string BriefReport() const;
};

// A method's own report of one sequence solve, returned with the result (as
// Ceres returns a Summary) so it lands in `hmc solve --diagnostics`: named
// numbers in the method's order (units in the names) and one line.
// Empty for the methods that have nothing beyond SolveSummary.
struct MethodReport {
  std::vector<std::pair<std::string, double>> values;
  std::string brief;
};

struct SolveResult {
  std::vector<MatX3d> meshes;  // one V x 3 mesh per input frame (mm)
  std::vector<FrameSolve> frames;
  SolveSummary summary;
  MethodReport report;
};

// What a solve accepts from bundles.csv and jaw.csv (docs/reliability.md):
// a stray frame number would make the dense range below enormous, a bundle
// far outside what the actor can reach would be taken as data (and lift the
// robust fit's noise estimate), and an impossible jaw pose would skin the
// neutral off the face. Group "input".
struct SequenceInputOptions {
  int max_frame_gap = 1000;  // most missing frames in a row between two
                             // frames of bundles.csv; a larger gap is an
                             // input error (decided before any allocation)
  double outlier_margin_mm = 10.0;  // a bundle farther than this outside
                                    // the box of every position the
                                    // dataset gives its marker (the jaw
                                    // taken out) is an outlier: flagged,
                                    // dropped from its frame (filled like
                                    // a missing marker); docs/reliability.md
  std::vector<double> jaw_open_deg = {-20.0, 60.0};  // [min, max] of open_deg
  double jaw_lateral_max_deg = 30.0;  // |lateral_deg| at most this
  double jaw_protrude_max_mm = 30.0;  // |protrude_mm| at most this

  void Register(OptionFields* fields);
  bool Check() const;
};

// A solve's input over a dense frame range, so the output stays aligned
// with frame numbers: one entry per frame number from the first to the last
// of bundles.csv. A frame without rows ("no bundles in this frame") or, when
// a jaw file is given, without a jaw pose ("no jaw pose for this frame in
// <jaw_name>") or with a jaw pose outside the options' range is marked bad
// by its frame_errors entry. `outliers` is sized (one empty list per frame)
// for DropBundlesBeyondReach.
struct DenseSequence {
  int first_frame = 0;
  std::vector<BundleFrame> frames;
  std::vector<JawPose> jaw;  // the zero pose without a jaw file
  std::vector<std::string> frame_errors;  // empty string: not known bad
  std::vector<std::vector<std::string>> outliers;  // per frame
  int num_outliers = 0;
  std::vector<std::string> unknown_markers;  // names not in the actor
  int unknown_rows = 0;                      // rows naming them
};
// rows: bundles.csv's frames (bundles_name: the file, for messages), sorted
// by frame number, not empty; jaw: jaw.csv's rows, or nullptr without a jaw
// file. Throws InputError naming bundles_name when two consecutive frames
// are more than options.max_frame_gap apart. Warns once about outliers and
// once about unknown marker names (with the names and the count).
DenseSequence MakeDenseSequence(const std::vector<BundleFrame>& rows,
                                const std::string& bundles_name,
                                const std::vector<JawFrame>* jaw,
                                const std::string& jaw_name,
                                const Actor& actor,
                                const SequenceInputOptions& options);

// Drops the bundles beyond their marker's reach: unskinned with their
// frame's jaw pose, farther than margin_mm outside the box of the positions
// the dataset gives the marker's surface point (the neutral and every
// shape), listing them in d->outliers (warned once, with the first). A
// face does not leave its dataset's range by more than a fraction of it; a
// bundle that does is a wrong name or a bad triangulation, and the solve
// would otherwise move the surface onto it (its interpolation step follows
// a residual beyond the noise).
void DropBundlesBeyondReach(const ShapeData& data, double margin_mm,
                            const std::string& bundles_name, DenseSequence* d);

// "" when `pose` is inside the options' range, else what is out of range.
std::string JawPoseRangeError(const JawPose& pose,
                              const SequenceInputOptions& options);

// Step 1 of the sequence driver for a solver: result->frames gets one
// FrameSolve per frame; solve(int f, const JawPose& pose, FrameSolve* out)
// fills frame f's (pose: jaw[f], the zero pose when jaw is empty) unless
// frame_errors (empty or one per frame) marks it bad; then it is a
// FrameSolve with that reason and num_bundles unused bundles. In frame
// order, one at a time, so `solve` may look at earlier frames' records.
template <typename Solve>
void SolveFrames(const std::vector<BundleFrame>& frames,
                 const std::vector<JawPose>& jaw,
                 const std::vector<std::string>& frame_errors, int num_bundles,
                 const std::string& progress_label, Solve&& solve,
                 SolveResult* result) {
  HMC_CHECK(jaw.empty() || jaw.size() == frames.size());
  const int F = static_cast<int>(frames.size());
  std::vector<FrameSolve>& out = result->frames;
  out.assign(F, FrameSolve());
  auto pose = [&](int f) { return jaw.empty() ? JawPose() : jaw[f]; };
  VisitFrames(
      F, frame_errors, progress_label,
      [&](int f) { solve(f, pose(f), &out[f]); },
      [&](int f, const std::string& reason) {
        FrameSolve& bad = out[f];
        bad.frame = frames[f].frame;
        bad.jaw = pose(f);
        bad.bundles.resize(num_bundles);
        bad.reason = reason;
      });
}

// Step 2: every bad frame's mesh (result->frames[f].ok false) repeats the
// previous good frame's mesh; before the first good frame, the neutral
// skinned with the frame's jaw pose (rig: the actor's jaw rig, or nullptr).
// Logs each bad frame with its reason; sets result->summary.bad_frames.
// result->meshes: one per frame, the good ones filled.
void FillBadMeshes(const TriMesh& neutral, const JawRig* rig,
                   SolveResult* result);

// Where a sequence solve's meshes go when the solve is not to hold them
// (issue 46: a long take's meshes are written as they are solved): called
// once per frame, in frame order, with the frame's record and its final
// mesh (V x 3, mm; a bad frame's filled as FillBadMeshes fills it), which
// the solve releases after the call. With a sink SolveResult::meshes
// comes back empty.
using MeshSink = std::function<void(int f, const FrameSolve& frame, const MatX3d& mesh)>;

// FillBadMeshes for a solve that hands its meshes to a sink as they come:
// Good(f, mesh) or Bad(f) for every frame in frame order, then Finish()
// (the warnings FillBadMeshes logs, summary.bad_frames). Holds one mesh:
// the last good frame's, which a bad frame repeats.
class MeshStream {
 public:
  MeshStream(const TriMesh& neutral, const JawRig* rig, SolveResult* result,
             const MeshSink& sink)
      : neutral_(neutral), rig_(rig), result_(result), sink_(sink) {}
  void Good(int f, MatX3d mesh);
  void Bad(int f);
  void Finish();

 private:
  const TriMesh& neutral_;
  const JawRig* rig_;
  SolveResult* result_;
  const MeshSink& sink_;
  MatX3d last_good_;
  bool any_good_ = false;
};

// Hands a solve's held meshes to `sink` in frame order, releasing each
// (the methods that hold their meshes anyway, so that every method can
// stream to a sink).
void DrainMeshes(const MeshSink& sink, SolveResult* result);

}  // namespace hmc
