// Rig calibration from the helmet tags (`hmc calibrate`; method:
// docs/calibration.md). The cameras and the AprilTags are rigid on the
// helmet, so every frame shows each tag at the same place in each camera
// (up to sensor noise); the face and its motion do not enter.
//
// The solve (Ceres, Huber loss of scale huber_px on each corner's residual):
//
//   min  sum_{frames f, cameras c, tags t, corners k}
//          rho( | Project(K_c, cam_c_from_helmet helmet_from_tag_t X_k) - u_fctk |^2 )
//
// over every camera's cam_from_helmet and every tag's helmet_from_tag
// (rotations as unit quaternions on Ceres' EigenQuaternionManifold), X_k the
// tag's corners in its own frame (+-size/2), Project the project's templated
// Kannala-Brandt projection (core/camera_fisheye.h). With refine =
// intrinsics also each camera's focal length (fx, with fy / fx kept) and
// principal point; they are kept only if the covariance of the solve
// determines the focal length to max_focal_sigma_pct, else the report says
// by how much it is undetermined and the extrinsics are solved alone.
//
// Gauge. With tag_layout = fixed (default) the nominal tag poses are
// trusted (the helmet's tag layout, measured once) and held constant: they
// define helmet space and only the cameras are solved. With tag_layout =
// free the tags are solved too and the solve holds cam0 at its nominal
// pose; with gauge = tags the result is then moved by the rigid transform
// that best aligns the solved tag corners with the nominal ones (Umeyama, no
// scale), with gauge = cam0 it stays at cam0's nominal pose. Measured on
// synthetic footage (docs/calibration.md): free tags leave each camera's
// pose 5x less accurate (0.1-0.15 mm, 0.03 deg against 0.02 mm, 0.005 deg),
// because a 22 mm tag's orientation is poorly determined by its corners;
// cam1_from_cam0 is as good either way.
//
// A mid-shot change of the rig (a camera knocked): per camera, the tag
// corners over the sampled frames are split at the frame that best divides
// them into two constant parts; a split whose parts differ by more than
// knock_px (RMS over the corners) is a change of the rig at that frame.
// Each part must hold two frames (corner medians per part), so one bad
// detection cannot pass for a knock; a change within the first or last
// sampled interval of the range is therefore not seen.
#pragma once

#include <array>
#include <filesystem>
#include <string>
#include <vector>

#include "core/calibration.h"
#include "core/options.h"
#include "core/types.h"
#include "tracking/footage_reader.h"
#include "tracking/tag_detector.h"

namespace hmc {

struct CalibrateOptions {
  FootageOptions footage;          // cam0, cam1, frames, offset1 (top level)
  int sample = 30;                 // frames spread over the shot on which tags are detected
  std::string refine = "extrinsics";  // extrinsics | intrinsics (also focal length, principal point)
  std::string tag_layout = "fixed";  // fixed (nominal tag poses trusted) | free (tags solved too)
  std::string gauge = "tags";      // with tag_layout free: tags (aligned with the nominal layout) | cam0
  double huber_px = 1;             // Huber loss scale on a corner's residual (px)
  double knock_px = 0.5;           // corners of a camera moving by more than this between two parts of the shot: the rig changed (px RMS)
  double max_focal_sigma_pct = 0.1;  // refine intrinsics only if the tags determine the focal length to this (%)
  double max_move_mm = 20;         // a camera solved farther than this from its nominal position: refused (swapped, duplicated, another rig)
  double max_turn_deg = 5;         // a camera solved turned more than this from its nominal: refused likewise
  int max_iterations = 100;        // Ceres iterations
  int threads = 0;                 // worker threads (0 = all cores)
  TagDetectorOptions tags;         // tags.*

  void Register(OptionFields* fields);
  bool Check() const;
};

// One tag seen in one camera in one frame.
struct TagObservation {
  int frame = 0;
  int camera = 0;   // index into the rig's cameras
  int tag = 0;      // index into the rig's tags
  std::array<Vec2, 4> corners;  // px, HelmetTag::CornersInHelmet order
};

struct RigChange {
  bool found = false;
  std::string camera;
  int frame = 0;          // the first frame of the changed rig
  int last_before = 0;    // the last frame before it that was examined
  double shift_px = 0;    // RMS shift of the camera's tag corners
};

struct CameraCalibrationReport {
  std::string name;
  int detections = 0;     // tag sightings
  double rms_px = 0;      // corner reprojection error
  double max_px = 0;
  double moved_mm = 0;    // camera centre: solved - nominal
  double turned_deg = 0;  // rotation: solved vs nominal
  double focal_change_px = 0;  // fx solved - nominal (0 unless intrinsics kept)
  double principal_change_px = 0;
  double focal_sigma_pct = 0;  // with refine intrinsics: 1-sigma of fx from the solve's covariance (%)
  bool intrinsics_refined = false;
};

struct TagCalibrationReport {
  int id = 0;
  std::vector<int> detections;  // per camera
  double rms_px = 0;
  double max_px = 0;
  double moved_mm = 0;    // tag centre: solved - nominal
  double turned_deg = 0;
};

struct CalibrateSummary {
  int frames_sampled = 0;
  int observations = 0;
  double rms_px = 0;
  double max_px = 0;
  double relative_moved_mm = 0;   // cam1_from_cam0 (camera 1 vs 0): change of the baseline (mm)
  double relative_turned_deg = 0;
  std::string intrinsics_note;    // what refine = intrinsics found
  RigChange change;
  double seconds = 0;
  std::string BriefReport() const;
};

// How far rig `a` is from rig `b` (e.g. the solve from the truth): per
// camera the centre's distance (mm) and the rotation angle (deg), the same
// for cam1_from_cam0 (camera 1 relative to camera 0), the focal lengths.
struct RigDifference {
  std::vector<double> camera_mm, camera_deg, focal_px;
  double relative_mm = 0, relative_deg = 0;
  std::string BriefReport() const;
};
RigDifference CompareRigs(const HelmetRig& a, const HelmetRig& b);

struct CalibrateOutput {
  HelmetRig rig;                                 // the calibrated rig
  std::vector<CameraCalibrationReport> cameras;
  std::vector<TagCalibrationReport> tags;
  std::vector<int> frames;                       // sampled frames
  std::vector<std::vector<double>> frame_rms_px;  // per sampled frame, per camera (NaN: no tag)
  CalibrateSummary summary;
  bool has_truth = false;   // set by the caller with a truth rig to compare
  RigDifference truth;      // the calibrated rig vs that truth
};

// The solve on given observations (no footage). Throws InputError if no
// camera sees a tag, or a camera sees none.
CalibrateOutput SolveRigFromTags(const HelmetRig& nominal,
                                 const std::vector<TagObservation>& observations,
                                 const CalibrateOptions& options);

// The largest change of the rig among `observations` (frames in order), as
// described above; found = false if no camera's split exceeds knock_px.
RigChange FindRigChange(const HelmetRig& nominal, const std::vector<TagObservation>& observations,
                        double knock_px);

// Detections in `image` (grey) of camera `camera` matched to the rig's tags
// by id (ids not in the rig are dropped).
std::vector<TagObservation> DetectRigTags(const TagDetector& detector, const HelmetRig& rig,
                                          int frame, int camera, const cv::Mat& image);

// The whole command: reads `shot`'s footage (sizes checked against the
// nominal calibration, naming the key), detects the tags on `sample` frames
// spread over the range, looks for a rig change (then, reading the frames
// between the samples, pins it to its frame), and solves. If the rig
// changed, `output.summary.change.found` is set and the rig is not solved
// (the caller refuses; choose one side with `frames`).
CalibrateOutput RunCalibrate(const std::filesystem::path& shot,
                             const std::filesystem::path& nominal_path, const HelmetRig& nominal,
                             const CalibrateOptions& options);

// The report as JSON text (docs/formats.md, "calibrate report").
std::string CalibrationReportJson(const CalibrateOutput& output);

}  // namespace hmc
