// Stereo (in general multi-view) triangulation of labelled 2D dots into 3D
// bundles in helmet space (`hmc triangulate`; method: docs/calibration.md,
// "Triangulation").
//
// For every frame and marker seen by at least two cameras:
//  1. each observed pixel u_c is unprojected with the project's own
//     Kannala-Brandt inverse (core/camera_fisheye.h, exact beyond 90 degrees
//     off axis) to a ray o_c + t d_c in helmet space (o_c the camera centre);
//  2. the initial point is the least-squares "midpoint" of the rays,
//       p0 = argmin_p sum_c |(I - d_c d_c^T)(p - o_c)|^2,
//     which for two rays is the midpoint of their common perpendicular;
//  3. p is refined by Gauss-Newton on the reprojection error in the fisheye
//     images,
//       E(p) = sum_c |Project_c(cam_c_from_helmet p) - u_c|^2   (px^2),
//     with exact Jacobians (ceres::Jet through Camera::Project);
//     for two views this is the optimal (maximum-likelihood under isotropic
//     pixel noise) two-view triangulation;
//  4. the pair is gated: a view whose residual exceeds gate_px means a
//     mislabel or a bad detection; the marker-frame is dropped, counted and
//     listed (status "gated");
//  5. the stereo consistency test: the refined cost E of a correct bundle
//     under isotropic pixel noise sigma is sigma^2 chi^2(2V - 3). sigma is
//     estimated robustly from the shot itself (the median of E over the
//     bundles divided by the chi^2 median, floored at 0.01 px, the centroid
//     precision of 8-bit footage), and a bundle whose E exceeds
//     sigma^2 q_{1-p} of chi^2(2V - 3) (p = consistency_p) is dropped with
//     status "inconsistent". Such bundles are mostly dots cut by an occluder
//     or the lip line in both views, whose centroids are biased each its own
//     way: well inside gate_px, yet their rays miss by more than noise does.
//     A batch test over the whole run (it needs the run's median); skipped
//     below 20 bundles. The default p (1e-4) drops only clear misses: a biased bundle
//     that is the last on its part of the face (the lower lip at a wide
//     opening) is worth more to the solve than none (docs/calibration.md).
// A marker seen by one camera only is not a bundle: its ray goes to rays.csv.
//
// Depth uncertainty: with J the 2V x 3 Jacobian of the residuals at p and
// s^2 = max(E / (2V - 3), noise_px^2) the pixel variance (from the residuals,
// floored at the tracks' expected accuracy), Cov(p) = s^2 (J^T J)^-1 and the
// depth uncertainty along the first camera's ray d is sqrt(d^T Cov(p) d).
#pragma once

#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "core/calibration.h"
#include "core/frame_data.h"
#include "core/day_markers.h"
#include "core/options.h"
#include "core/tracks_2d.h"
#include "core/types.h"

namespace hmc {

struct TriangulateOptions {
  DayMarkersOptions day;          // markers: the day's markers, for the rim offsets (core/day_markers.h)
  double gate_px = 2.0;           // largest reprojection residual of a view after refinement (px)
  double noise_px = 0.1;          // expected accuracy of the tracks (px, floor of the uncertainty)
  double min_ray_angle_deg = 1.0;  // views whose rays meet at a smaller angle are not triangulated (deg)
  int max_iterations = 20;        // Gauss-Newton iterations of the refinement
  double consistency_p = 1e-4;    // false-rejection rate of the stereo consistency test (0 = off)
  int threads = 0;                // worker threads (0 = all cores)
  // The painted dot's offset (triangulation/dot_offset.h), applied when the
  // command is given the actor (--actor):
  double dot_radius = 1.2;        // painted dot radius (mm)
  double dot_fit_radius = 3;      // neutral vertices within this of the marker fit the skin's curvature (mm)

  void Register(OptionFields* fields);
  bool Check() const;
};

enum class TriangulationStatus {
  kOk,        // triangulated
  kGated,     // a view's residual exceeds gate_px: mislabel or bad detection
  kParallel,  // the rays meet at less than min_ray_angle_deg
  kBehind,    // the point lies behind a camera
  kNoRay,     // a pixel could not be unprojected (outside the lens model)
  kInconsistent,  // the views' rays miss each other by more than the shot's noise explains
};
const char* TriangulationStatusName(TriangulationStatus status);

// One marker-frame seen by two or more cameras.
struct TriangulationRecord {
  int frame = 0;
  std::string marker;
  TriangulationStatus status = TriangulationStatus::kOk;
  int views = 0;                     // cameras that saw the marker
  std::vector<double> residual_px;   // per rig camera: reprojection residual (px; NaN if not seen)
  double ray_angle_deg = 0;          // largest angle between two views' rays (deg)
  double depth_sigma_mm = 0;         // uncertainty along the first view's ray (mm)
  Vec3 p_in_helmet = Vec3::Zero();   // the refined point (mm; also for gated records)
};

// A marker seen by one camera only: the ray p = origin + t direction (t > 0).
struct MonoRay {
  int frame = 0;
  std::string marker;
  std::string camera;
  Vec3 origin_in_helmet = Vec3::Zero();     // camera centre (mm)
  Vec3 direction_in_helmet = Vec3::Zero();  // unit vector
};

struct TriangulateInput {
  const HelmetRig* rig = nullptr;
  const std::vector<Track2d>* tracks = nullptr;
  std::filesystem::path tracks_path;  // names the tracks in errors
  // Optional (triangulation/dot_offset.h): per marker the painted dot's rim
  // centre relative to the marker (mm); subtracted from each bundle.
  const std::map<std::string, Vec3>* dot_offsets = nullptr;
};

struct TriangulateSummary {
  int frames = 0;           // frames with any track
  int candidates = 0;       // marker-frames seen by >= 2 cameras
  int triangulated = 0;     // of which status ok
  int gated = 0;
  int parallel = 0;
  int behind = 0;
  int no_ray = 0;
  int inconsistent = 0;     // dropped by the stereo consistency test
  double pixel_noise_px = 0;      // the shot's pixel noise estimated by the test (0: not run)
  int mono = 0;             // marker-frames seen by one camera (rays.csv rows)
  double rms_residual_px = 0;     // over the triangulated views
  double max_residual_px = 0;
  double median_depth_sigma_mm = 0;
  double seconds = 0;       // triangulation only (no reading or writing)
  std::string BriefReport() const;
};

struct TriangulateOutput {
  std::vector<BundleFrame> bundles;          // status-ok points (helmet space, mm)
  std::vector<TriangulationRecord> records;  // every candidate, by (frame, marker)
  std::vector<MonoRay> rays;                 // by (frame, marker)
  TriangulateSummary summary;
};

// Throws InputError (naming input.tracks_path) if a track names a camera the
// rig does not have or the options are invalid.
TriangulateOutput RunTriangulate(const TriangulateInput& input,
                                 const TriangulateOptions& options);

// rays.csv: frame,marker,camera,ox,oy,oz,dx,dy,dz (helmet space; origin mm,
// unit direction; docs/formats.md). Atomic.
inline constexpr const char* kRaysCsvHeader = "frame,marker,camera,ox,oy,oz,dx,dy,dz";
void WriteRaysCsv(const std::filesystem::path& path,
                  const std::vector<MonoRay>& rays);
// Throws InputError with file and line on a bad row or a non-unit direction.
std::vector<MonoRay> ReadRaysCsv(const std::filesystem::path& path);

// triangulation.csv: frame,marker,status,views,residual_<camera>_px...,
// ray_angle_deg,depth_sigma_mm,x,y,z (docs/formats.md). Atomic.
void WriteTriangulationCsv(const std::filesystem::path& path,
                           const HelmetRig& rig,
                           const std::vector<TriangulationRecord>& records);

// Tracks from a synthetic shot's dots_2d.csv ground truth: `centroid` uses
// cx,cy of `full` dots (what a perfect tracker of the painted dot reports),
// `exact` uses x,y of every visible dot (the marker point's projection).
std::vector<Track2d> TracksFromDots(const std::vector<Dot2dTruth>& dots,
                                    bool centroid);

// Bundle error against the truth (same frames and markers, mm) and coverage.
struct TriangulationAccuracy {
  int compared = 0;           // triangulated marker-frames with a truth bundle
  double median_mm = 0;
  double rms_mm = 0;
  double p99_mm = 0;
  double max_mm = 0;
  int seen_both = 0;          // marker-frames full or partial in every camera (dots_2d)
  int seen_both_triangulated = 0;
  int full_both = 0;          // of which `full` in every camera (the dots with cx,cy)
  int full_both_triangulated = 0;
  double coverage() const {
    return seen_both > 0 ? static_cast<double>(seen_both_triangulated) / seen_both : 0;
  }
  double full_coverage() const {
    return full_both > 0 ? static_cast<double>(full_both_triangulated) / full_both : 0;
  }
  std::string BriefReport() const;
};
// `dots` may be empty (no coverage then).
TriangulationAccuracy EvaluateTriangulation(
    const std::vector<BundleFrame>& bundles,
    const std::vector<BundleFrame>& truth, const std::vector<Dot2dTruth>& dots,
    int num_cameras);

}  // namespace hmc
