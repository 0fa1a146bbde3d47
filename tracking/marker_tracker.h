// Naming and tracking the painted dots (docs/tracking.md):
//
// Labelling at the reference frame (Start):
//   1. Stereo pairs: every cam0 x cam1 pair of detections whose rays pass
//      within `pair_gap_mm` (stereo_rays.h) is a candidate 3D point (the
//      midpoint). Pairs whose detections have no other partner are
//      "unique" and seed the registration.
//   2. Rigid registration of the actor's neutral marker layout (head space)
//      to the candidate points: RANSAC over triples of unique points whose
//      pairwise distances match a triple of markers (within
//      `triple_tolerance_mm`), restricted to helmet_from_head within 1.5 x
//      (max_offset_mm, max_offset_deg) of the identity (helmet space is head
//      space at rest), scored by the markers with a candidate point within
//      `inlier_mm`; then ICP with mutual nearest neighbours and a shrinking
//      gate. Closed-form rigid fits: Umeyama 1991 (Eigen::umeyama).
//      With a jaw rig, the jaw pose is then searched too: the jaw is the
//      one large articulation of the markers, and a take may start with
//      the mouth open. On a grid over the actor's dataset jaw range
//      (widened), the pose whose skinned layout (core/jaw.h) puts the most
//      markers within `inlier_mm` of a candidate point (then the smallest
//      residual) wins, is refined on a finer grid, and ICP is redone with
//      the posed layout. Then the expression: the layout plus the
//      principal components of the dataset's marker displacements, its
//      weights started by a greedy search over the dataset's shapes and
//      refined by ICP whose rounds fit pose and weights jointly and
//      robustly (stabilization/head_fit.h); kept where it puts more
//      markers on points than the rigid fit, and at least half the
//      detections. The names of step 3 come from the layout chosen. A
//      failure says its likely cause (the calibration, from the stereo
//      rays' gaps; else the actor's markers or the reference frame).
//   3. Names, per camera: each marker facing the camera is projected with
//      the registered pose; a global assignment (tracking/assignment.h)
//      matches projections to detections within a gate of `name_gate` x
//      the distance to the nearest other projection. A match is kept only
//      if unambiguous: the second-nearest detection is more than
//      `ambiguity_ratio` x farther. Rounds follow in which an unnamed
//      marker's projection is corrected by the mean residual of its named
//      layout neighbours (the face is near, not at, neutral).
// Tracking (Step), per camera:
//   a tracked dot is predicted by pyramidal Lucas-Kanade flow of its
//   neighbourhood from the previous frame (Bouguet 2000, OpenCV; kept only
//   where the backward flow returns within `flow_check_px`), else at its
//   position plus its last motion; the predictions are matched to the
//   detections by one gated global assignment (two names never take one
//   dot), the gate a fraction of the distance to the nearest other dot.
//   Then the head pose is refitted (trimmed rigid fit of the layout to the
//   markers named in both cameras), with a jaw rig the jaw pose too (a
//   grid search within `jaw_reach_deg` of the previous frame's opening
//   minimising, over the jaw-moved markers of the posed layout, the
//   truncated squared distance to the marker's own triangulated point if
//   it is named in both cameras, else to the nearest point of any stereo
//   pair of detections, so a fast opening whose chin dots were lost is
//   still followed), and the lost and never-seen dots are named from the
//   layout at that jaw pose as at the reference frame (step 3) with the tighter
//   `reacquire_gate`: projection under the pose, corrected by the named
//   neighbours' residuals, unambiguous matches only. A dot named in both
//   cameras whose rays miss by more than `epipolar_gap_mm` is a swap: the
//   name is dropped in both for the frame. Last, the search for expected
//   dots (also at the reference frame): each marker still unnamed that
//   faces the camera is searched for (DetectDotNear, dot_detector.h) within
//   `search_gate` x the nearest-dot distance (at most half a dot diameter)
//   of where its named neighbours (else the flow) place it, with the ellipse
//   its normal predicts; a dot found is named where another camera sees
//   the marker on its ray (in rounds: the names given place their
//   neighbours for the next). A dot with no detection in its gate and none
//   found by the search is hidden: no row, the track is lost until
//   re-acquired.
// Dots lost mid-take (paint rubbed off; docs/tracking.md, "Dots lost
//   mid-take"): a marker named in both cameras in at least `lost_frames`
//   frames, then for `lost_frames` frames in a row named in neither and
//   missing in both where they see it squarely (view cosine > 0.5, placed
//   by at least two named neighbours, no unnamed detection within the
//   naming gate of its place; not beside the lips' opening), is lost from
//   the first of those frames: from then on a name it gets in one camera
//   only (an eyelid's edge where the dot was, a neighbour's dot) is
//   dropped, until it is named in both cameras again (the rays meeting:
//   the dot is back).
#pragma once

#include <array>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "core/actor.h"
#include "core/jaw.h"
#include "core/calibration.h"
#include "core/options.h"
#include "tracking/dot_detector.h"
#include "tracking/track_fixes.h"

namespace hmc {

struct MarkerTrackerOptions {
  double pair_gap_mm = 1.0;          // stereo pairing: largest ray closest-approach distance (mm)
  double max_offset_mm = 15;         // head offset from rest the labelling must cover (mm)
  double max_offset_deg = 10;        // head rotation from rest the labelling must cover (deg)
  double triple_tolerance_mm = 3;    // RANSAC: pairwise distance agreement of a triple (mm)
  double inlier_mm = 2.5;            // registration inlier distance (mm)
  int ransac_samples = 600;          // RANSAC triples of points tried
  double name_gate = 0.4;            // naming gate (fraction of the distance to the nearest other dot)
  double track_gate = 0.3;           // tracking gate (fraction of the distance to the nearest other dot)
  double reacquire_gate = 0.2;       // re-acquisition gate (fraction of the nearest-dot distance)
  double max_gate_px = 25;           // cap of every gate (px)
  double ambiguity_ratio = 2;        // second-nearest detection at least this much farther
  double epipolar_gap_mm = 1.5;      // stereo swap check: largest ray gap of a named pair (mm)
  int neighbours = 6;                // layout neighbours whose residuals correct a projection
  double flow_window = 3;            // Lucas-Kanade window (dot diameters)
  double flow_check_px = 0.5;        // largest forward-backward flow disagreement (px)
  double jaw_reach_deg = 8;          // largest jaw opening change between frames followed (deg)
  // Search for an expected dot the blind detector missed: radius (fraction
  // of the nearest-dot distance; 0 = off).
  double search_gate = 0.3;
  // A dot missing this many frames in a row where both cameras should see
  // it, after as many named in both, is lost (0 = never declared lost).
  int lost_frames = 3;

  void Register(OptionFields* fields);
  bool Check() const;
};

// The actor's neutral marker layout in head space.
struct MarkerLayout {
  std::vector<std::string> names;
  std::vector<Vec3> positions;            // head space (mm)
  std::vector<Vec3> normals;              // unit surface normals
  std::vector<std::vector<int>> neighbours;  // nearest markers on the neutral, nearest first
  std::vector<double> border_mm;  // distance to the neutral mesh's border (lips' opening, rim; mm)
  // The jaw: the actor's rig (without its per-vertex weights), each
  // marker's skinning weight (empty: no jaw rig), and the range of the
  // dataset's jaw poses widened by a quarter of it (at least 1 deg / mm).
  JawRig jaw_rig;
  std::vector<double> jaw_weights;
  std::array<double, 3> jaw_lower{}, jaw_upper{};
  // The dataset's expressions at the markers: the principal components of
  // its shapes' marker displacements (unskinned by each shape's jaw pose
  // with a jaw rig), 3K x P, rows 3k..3k+2 marker k, each column scaled to
  // the RMS of its coefficient over the dataset (mm); P = 0 without shapes.
  Eigen::MatrixXd expression_basis;
  // P x N: the dataset's shapes in that basis (column n: shape n).
  Eigen::MatrixXd expression_shapes;

  // The positions with the jaw at `pose` (as they are without a rig).
  std::vector<Vec3> PosedPositions(const JawPose& pose) const;
};
MarkerLayout MakeMarkerLayout(const Actor& actor, int neighbours);

// One camera's result for one frame.
struct CameraFrameTracks {
  std::vector<int> marker;     // per named dot: marker index
  std::vector<Vec2> pixel;     // its detection's centre
  std::vector<double> score;   // its detection's score
  int detections = 0;
  int unnamed = 0;             // detections left without a name
  int lost = 0;                // tracks that ended this frame (dot hidden or not found)
  int reacquired = 0;          // names given to dots that were lost or never seen
  int swaps_caught = 0;        // names dropped by the stereo check
  int searched = 0;            // names given to dots found by the search for expected dots
  int lost_dropped = 0;        // names dropped: their marker is lost (MarkerTracker::lost_since)
  bool skipped = false;        // the camera's image was missing
  // Markers left unnamed that face the camera squarely, placed by named
  // neighbours, with no detection where their dot should be: not painted,
  // or painted elsewhere (marker_tracker.cc, NameFromLayout).
  std::vector<int> vacant;
};

// One fix of track_fixes.csv (tracking/track_fixes.h) resolved for the
// tracker: markers as layout indices (-1: none given).
struct TrackerFix {
  TrackFixAction action = TrackFixAction::kRename;
  int marker = -1;
  int to = -1;  // rename
  bool has_pixel = false;
  Vec2 pixel = Vec2::Zero();
};

// What applying one frame's fixes did, per camera.
struct FixOutcome {
  int applied = 0;
  std::vector<int> unmatched;  // indices into the frame's fixes of the camera: no dot found
};

struct ReferenceLabelling {
  bool ok = false;
  std::string reason;          // why not, when !ok
  Rigid3 helmet_from_head = Rigid3::Identity();
  JawPose jaw;                 // the jaw pose found (zero without a jaw rig)
  int candidate_points = 0;    // stereo pairs within the gap
  double paired_share = 0;     // least over the cameras: share of its detections in a stereo pair
  double median_gap_mm = 0;    // median over cam0's detections of the smallest ray gap to cam1's
  int rigid_inliers = 0;       // markers on a point under the rigid (and jaw) registration
  int expression_inliers = 0;  // the same with the dataset's expression fitted (step 2, last)
  bool expression = false;     // the names come from the expressed layout
  int inliers = 0;             // markers matched by the registration
  double rms_mm = 0;           // registration residual over the inliers
};

class MarkerTracker {
 public:
  // `detect`: the detector's options, for the search for expected dots.
  MarkerTracker(const HelmetRig& rig, const MarkerLayout& layout,
                const MarkerTrackerOptions& options,
                const DotDetectorOptions& detect = DotDetectorOptions());

  // Labels the reference frame (file comment). Per camera the named dots;
  // labelling() tells how the registration went.
  // images: per camera the frame (CV_8U or CV_16U grey) the detections
  // come from; dot_size_px: per camera, sets the flow window.
  // fixes: per camera the frame's track fixes (null: none), applied as
  // hard constraints after the naming (ApplyFixes); the tracking goes on
  // from the fixed names. outcome: per camera what they did.
  std::vector<CameraFrameTracks> Start(const std::vector<std::vector<DotDetection>>& blind,
                                       const std::vector<cv::Mat>& images,
                                       const std::vector<double>& dot_size_px,
                                       const std::vector<std::vector<TrackerFix>>* fixes = nullptr,
                                       std::vector<FixOutcome>* outcome = nullptr);
  // The next frame; a camera whose image is missing has an empty image.
  std::vector<CameraFrameTracks> Step(const std::vector<std::vector<DotDetection>>& blind,
                                      const std::vector<cv::Mat>& images,
                                      const std::vector<std::vector<TrackerFix>>* fixes = nullptr,
                                      std::vector<FixOutcome>* outcome = nullptr);

  const ReferenceLabelling& labelling() const { return labelling_; }

  // Per marker: the frame (0: the reference frame Start labelled, n: the
  // n-th Step after it) from which its dot is lost (file comment), -1 if
  // it is not. A marker whose dot is back is -1 again.
  const std::vector<int>& lost_since() const { return lost_since_; }

 private:
  enum class Status { kNone, kTracked, kLost };
  struct DotState {
    Status status = Status::kNone;
    bool has_position = false;
    Vec2 position = Vec2::Zero();
    Vec2 velocity = Vec2::Zero();
  };
  // How camera c sees the layout `positions` (head space) under
  // helmet_from_head_, per marker.
  struct LayoutView {
    std::vector<char> facing;      // in the image, view cosine > 0.1
    std::vector<char> squarely;    // view cosine > kSquarelyCos
    std::vector<Vec2> projection;  // projected marker point (px)
    std::vector<double> cos;       // view cosine at the marker
    std::vector<Vec2> normal_dir;  // image direction of the surface normal (unit)
  };
  LayoutView ViewLayout(int c, const std::vector<Vec3>& positions) const;
  // Marker k's projection corrected by the mean residual of its named,
  // facing layout neighbours (the face is not at neutral); returns how
  // many neighbours corrected it.
  int CorrectedProjection(int k, const LayoutView& view,
                          const std::vector<DotDetection>& detections,
                          const std::vector<int>& detection_of, Vec2* prediction) const;
  // The search for the dots the blind detector missed (docs/tracking.md,
  // "Searching for an expected dot"): per camera, each marker still
  // unnamed that faces it is searched for where it is expected (its
  // projection corrected by its named neighbours, else `tracked[c]`, the
  // flow's prediction, where `has_tracked[c]`), with the ellipse its
  // normal predicts; a dot found is appended to (*detections)[c] and named
  // where another camera sees the marker on its ray (named there or found
  // there too). Returns per camera the names given.
  std::vector<int> SearchExpected(const std::vector<cv::Mat>& images,
                                  const std::vector<std::vector<Vec2>>& tracked,
                                  const std::vector<std::vector<char>>& has_tracked,
                                  std::vector<std::vector<DotDetection>>* detections,
                                  std::vector<std::vector<int>>* detection_of) const;
  // SearchExpected in rounds while a round names a dot (the names it gives
  // place their neighbours); adds to (*out)[c].searched.
  void SearchInRounds(const std::vector<cv::Mat>& images,
                      const std::vector<std::vector<Vec2>>& tracked,
                      const std::vector<std::vector<char>>& has_tracked,
                      std::vector<std::vector<DotDetection>>* detections,
                      std::vector<std::vector<int>>* detection_of,
                      std::vector<CameraFrameTracks>* out) const;
  void Register(const std::vector<std::vector<DotDetection>>& detections);
  // Gated assignment of predictions to detections; fills `tracks`.
  void Match(int camera, const std::vector<DotDetection>& detections,
             const std::vector<Vec2>& prediction, const std::vector<char>& predicted,
             const std::vector<double>& gate_fraction, bool require_unambiguous_all,
             std::vector<int>* detection_of) const;
  // Names unnamed markers of camera c from the layout `positions` (head
  // space) under helmet_from_head_ (file comment, step 3), in rounds.
  // With `vacant`, adds the markers whose place holds no dot
  // (CameraFrameTracks::vacant).
  void NameFromLayout(int c, const std::vector<Vec3>& positions,
                      const std::vector<DotDetection>& detections, double gate_fraction,
                      bool allow_uncorrected, std::vector<int>* detection_of,
                      std::vector<int>* vacant = nullptr) const;
  // Dots lost mid-take (file comment), after every naming step of a frame
  // but the fixes: counts each marker's frames named in both cameras and
  // those it is missing in a row, declares it lost or back, and drops the
  // one-camera names of a lost marker.
  void UpdateLost(const std::vector<std::vector<DotDetection>>& detections,
                  const std::vector<bool>& present, std::vector<std::vector<int>>* detection_of,
                  std::vector<CameraFrameTracks>* out);
  // Whether marker k's dot is missing where it should be seen in the camera of `view`
  // (UpdateLost).
  bool MissingWhereSeen(int k, const LayoutView& view,
                        const std::vector<DotDetection>& detections,
                        const std::vector<int>& detection_of,
                        const std::vector<char>& named) const;
  // helmet_from_head_ from the markers named in both cameras (trimmed fit),
  // then jaw_ and positions_ (with a jaw rig).
  void UpdateHeadPose(const std::vector<std::vector<DotDetection>>& detections,
                      const std::vector<std::vector<int>>& detection_of);
  void StereoCheck(const std::vector<std::vector<DotDetection>>& detections,
                   std::vector<std::vector<int>>* detection_of,
                   std::vector<CameraFrameTracks>* out) const;
  // The frame's fixes of camera c, after every other naming step so
  // that nothing undoes them: rename and move give the marker the dot
  // (taking it from whoever held it: that marker is lost and re-acquired
  // later), unname takes the name off the dot and bars it (below), absent
  // keeps the marker unnamed in this camera until a later rename or move
  // names it. A move to where no dot was detected adds the point as a
  // detection (score 1). First the barred dots `barred` (detection
  // indices, -1: not found) lose their names, and the confusions fixed
  // before are undone (ResolveConfusions); last every absent marker is
  // unnamed. Leaves in barred_[c] the barred dots' positions. A rename of
  // a dot marker A held to marker B records the confusion (A, B).
  FixOutcome ApplyFixes(int c, const std::vector<TrackerFix>& fixes, const std::vector<int>& barred,
                        std::vector<DotDetection>* detections, std::vector<int>* detection_of);
  // ApplyFixes for every camera present (no fixes: only the barred dots
  // and absent markers unnamed). Returns the detections the names point
  // into: the frame's, or `storage` holding them with the fixes' added
  // points.
  const std::vector<std::vector<DotDetection>>& ApplyFrameFixes(
      const std::vector<std::vector<DotDetection>>& detections, const std::vector<bool>& present,
      const std::vector<std::vector<TrackerFix>>* fixes,
      const std::vector<std::vector<int>>& barred, std::vector<FixOutcome>* outcome,
      std::vector<std::vector<DotDetection>>* storage, std::vector<std::vector<int>>* detection_of);
  // A confusion a rename fixed, (A, B): marker A had taken B's dot. On a
  // later frame where A holds a dot and B none, the dot goes to B if it is
  // nearer B's place than A's (each marker's projection under the current
  // pose, corrected by its named neighbours, the two taken out of each
  // other's correction): the tracker's re-acquisition and flow repeat
  // a confusion when B's dot is lost and found again (docs/review.md).
  void ResolveConfusions(int c, const std::vector<DotDetection>& detections,
                         std::vector<int>* detection_of) const;
  // Camera c's barred dots followed into the frame whose flow pyramid is
  // `pyramid`: per barred dot of barred_[c] the detection it is now (-1:
  // not found, the bar ends) -- its flow from the previous frame (else its
  // position), then the nearest detection within half a dot diameter.
  std::vector<int> FollowBarred(int c, const std::vector<cv::Mat>& pyramid,
                                const std::vector<DotDetection>& detections) const;
  // The detection a fix points at: the nearest to its pixel within half
  // the dot's size (at least 3 px), else (not a move) the one its marker
  // holds; -1: none.
  int FixedDot(int c, const TrackerFix& fix, const std::vector<DotDetection>& detections,
               const std::vector<int>& detection_of) const;

  HelmetRig rig_;
  MarkerLayout layout_;
  MarkerTrackerOptions options_;
  DotDetectorOptions detect_;
  ReferenceLabelling labelling_;
  std::vector<std::vector<DotState>> state_;  // [camera][marker]
  std::vector<std::vector<char>> absent_;     // [camera][marker]: set by an `absent` fix
  // [camera]: the dots an `unname` fix took the name off (px), followed
  // frame to frame and given no name until a fix names them or they are
  // not found.
  std::vector<std::vector<Vec2>> barred_;
  // [camera]: the confusions (A, B) renames fixed (ResolveConfusions).
  std::vector<std::vector<std::pair<int, int>>> confused_;
  std::vector<std::vector<cv::Mat>> pyramid_;  // [camera]: previous frame's flow pyramid
  std::vector<double> dot_size_px_;
  Rigid3 helmet_from_head_ = Rigid3::Identity();
  JawPose jaw_;                  // the current jaw pose (labelled, then refitted per frame)
  std::vector<Vec3> positions_;  // the layout at jaw_ (head space)
  // Dots lost mid-take, per marker (UpdateLost): frames named in both
  // cameras, frames missing in a row and the first of them, and
  // lost_since().
  int frame_ = 0;  // 0 at Start, +1 per Step
  std::vector<int> stereo_frames_, missing_frames_, missing_since_, lost_since_;
};

}  // namespace hmc
