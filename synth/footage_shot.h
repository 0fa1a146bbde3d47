// A whole synthetic shot (`hmc synth shot`): the helmet rig around the
// actor, a performance, both cameras' footage rendered frame by frame, and
// the exact ground truth, written to a shot folder (docs/formats.md, "Shot
// folder"; method: docs/footage.md).
#pragma once

#include <filesystem>
#include <string>

#include "core/actor.h"
#include "core/options.h"
#include "synth/face_model.h"
#include "synth/footage.h"
#include "synth/helmet_rig.h"
#include "synth/paint.h"
#include "synth/performance.h"
#include "synth/shot_variation.h"

namespace hmc {

struct SynthShotOptions {
  PerformanceOptions performance;  // frames, seed, fps, slip, vibration (top level)
  std::string video = "ffv1";      // ffv1 (lossless .mkv per camera) | h264 (lossy .mp4 per camera) | png (a folder per camera) | none (ground truth only: no images, dots_2d.csv or contact sheet)
  double bundle_noise_mm = 0;      // > 0: also write bundles_helmet_noisy.csv, Gaussian noise of this std per coordinate (mm)
  int contact_frames = 4;          // frames on the contact sheet (0 = none)
  bool contact_dots = true;        // overlay the ground-truth dots on the contact sheet
  double contact_scale = 0.4;      // contact sheet image scale
  int threads = 0;                 // worker threads (0 = all cores)
  HelmetRigOptions rig;            // rig.*
  FootageRenderOptions render;     // render.*
  ShotVariationOptions vary;       // vary.*: the render options drawn per seed (off by default)
  PaintOptions paint;              // paint_*: the day's paint (synth/paint.h)
  // Calibration tests (docs/calibration.md, "Synthetic harness"): with any
  // nominal_* > 0, calibration.yaml is a perturbed "nominal" rig and the true
  // one is written beside it as calibration_true.yaml.
  double nominal_mm = 0;           // each camera's centre moved by this (mm, random direction)
  double nominal_deg = 0;          // each camera rotated by this (deg, random axis)
  double nominal_focal_pct = 0;    // each camera's fx, fy scaled by 1 +- this (%)
  int knock_frame = 0;             // from this frame on, knock_camera is moved (0 = no knock)
  std::string knock_camera = "cam1";  // the camera knocked
  double knock_mm = 1;             // the knock's translation (mm, random direction)
  double knock_deg = 0.5;          // the knock's rotation (deg, random axis)

  void Register(OptionFields* fields);
  bool Check() const;
};

struct SynthShotSummary {
  int frames = 0;
  int cameras = 0;
  double render_seconds = 0;      // rendering only (both cameras, all frames)
  double total_seconds = 0;       // everything, writing included
  double max_edge_error_px = 0;   // largest rasterized edge sagitta
  double split_fraction = 0;      // front-facing triangles that were subdivided
  double mean_visible_dots = 0;   // per frame and camera
  double mean_full_dots = 0;      // of which wholly visible, not grazing (disc full)
  std::string BriefReport() const;
};

// `rig` with every camera's pose and focal length perturbed as
// SynthShotOptions::nominal_* say (seeded, deterministic).
HelmetRig PerturbRig(const HelmetRig& rig, double mm, double deg, double focal_pct,
                     uint64_t seed);
// `cam_from_helmet` moved by a rigid change of `mm` and `deg` about the
// camera centre (seeded direction and axis).
Rigid3 KnockPose(const Rigid3& cam_from_helmet, double mm, double deg, uint64_t seed);

// The helmet rig the shot uses for `model`'s face.
HelmetRig MakeShotRig(const FaceModel& model, const HelmetRigOptions& options);

// Renders the shot of `actor` (the package `model` was checked against) into
// `out_dir`. Throws InputError if the options are invalid or a file cannot
// be written.
SynthShotSummary RunSynthShot(const FaceModel& model, const Actor& actor,
                              const SynthShotOptions& options,
                              const std::filesystem::path& out_dir);

}  // namespace hmc
