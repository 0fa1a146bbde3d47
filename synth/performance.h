// What happens in front of the helmet cameras during a synthetic shot: the
// actor's expression trajectory (the generator's animated performance,
// synth/truth_frames.h: smooth onsets and holds, overlapping units,
// speech-like jaw and lip motion, blinks), a slow rigid slip of the head
// inside the helmet and a small high-frequency vibration of the helmet (the
// cameras and tags, rigid together) against the head. Both motions are
// folded into head_from_helmet per frame, so the rig stays one rigid
// calibration for the whole shot. Deterministic by seed.
#pragma once

#include <vector>

#include <Eigen/Core>

#include "core/options.h"
#include "core/types.h"
#include "synth/face_model.h"

namespace hmc {

struct PerformanceOptions {
  int frames = 120;             // number of frames
  int seed = 1;                 // random seed of expressions, slip and vibration
  double fps = 30;              // frame rate (frames per second)
  double slip_mm = 2.5;         // largest slip of the head in the helmet (mm)
  double slip_deg = 1.5;        // largest slip rotation (deg)
  double vibration_mm = 0.12;   // amplitude of the helmet vibration (mm)
  double vibration_deg = 0.04;  // amplitude of the vibration's rotation (deg)
  double vibration_hz = 11;     // main vibration frequency (Hz)
  double head_offset_mm = 0;    // head placed this far from rest for the whole shot, random direction (mm)
  double head_offset_deg = 0;   // and turned this much about a random axis through the head origin (deg)
  double brow_activity = 0;     // peak of added slow brow raises/lowerings (activation; 0 = none)
  double jaw_activity = 0;      // peak of added slow jaw opening, swing, thrust (activation; 0 = none)
  double expression_scale = 1;  // the performance's activations scaled by this (0 = a neutral hold)

  void Register(OptionFields* fields);
  bool Check() const;
};

struct ShotPerformance {
  double fps = 30;
  std::vector<Eigen::VectorXd> activations;  // per frame: K unit activations
  std::vector<Rigid3> head_from_helmet;      // per frame
};

ShotPerformance MakePerformance(const FaceModel& model,
                                const PerformanceOptions& options);

// head_from_helmet at time t_s (seconds from frame 0), the smooth function
// MakePerformance samples; used for motion blur between frames.
Rigid3 HeadFromHelmetAt(const PerformanceOptions& options, double t_s);

// The activations at time t (in frames from frame 0, between two frames
// for motion blur): the Catmull-Rom spline through the frames around it
// (the ends repeated), each unit kept within the two frames it lies
// between. Smooth through the frames, unlike a straight line from frame to
// frame: with a kink at every frame, the average over a shutter centred on
// a frame lies 0.075 x the trajectory's second difference (per frame^2)
// off the frame's own state for 5 samples over half a frame (on a fast jaw
// opening a dot's image 1-2.6 px off the frame's truth), where a smooth
// motion of acceleration a puts it a s^2 / 24 off for a shutter of s
// frames (0.010 a for half a frame), as a real camera records it.
Eigen::VectorXd ActivationsAt(const ShotPerformance& performance, double t);

}  // namespace hmc
