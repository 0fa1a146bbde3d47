// `hmc register` (docs/registration.md): the day's markers from a neutral
// (or range-of-motion) take. Every shoot day the dots are painted again,
// each a millimetre or more off the package's marker point; registration
// finds where each painted dot sits on the actor's neutral:
//  1. the take's dots are tracked (tracking/track_shot.h) with the
//     labelling's tolerances widened by the paint's expected offset, and
//     triangulated (triangulation/triangulate.h);
//  2. each frame's head pose is fitted to the package's markers
//     (stabilization/stabilize.h: rigidly, then with the expression the
//     dataset explains) and each dot's bundles are brought to head space;
//  3. the pose's common error (the painted offsets' own rigid part, which
//     the marker fit cannot tell from head motion) is removed by fitting
//     the dots' mean positions to the neutral's surface (point to plane,
//     robust): the dots lie on the skin wherever they are painted;
//  4. each dot's mean is projected onto the surface (closest point), with
//     its uncertainty (the spread of its positions over the frames), and
//     the dots are named by the paint's prior: the assignment of dots to
//     the package's markers with the least sum of squared offsets;
//  5. a second pass tracks the take again with the day's markers of pass 1
//     (names given from where the dots really are), and registers again.
// Reported: markers not found (not painted), markers that move against
// the surface over the take (loose or smeared paint, or a wrong name) and
// markers off the surface.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "core/actor.h"
#include "core/options.h"
#include "tracking/track_shot.h"

namespace hmc {

struct RegisterOptions {
  TrackOptions track;          // the tracking of the take (frames, detect.*, track.*)
  double paint_offset_mm = 6;  // largest painted offset the labelling must allow (mm)
  int passes = 2;              // track-and-register passes (2: the second names the dots from the first's markers)
  double min_frames = 0.5;     // a marker found in fewer than this fraction of the frames is reported not found
  double loose_mm = 0.3;       // a marker whose RMS motion against the surface over the take exceeds this is reported (mm)
  double off_surface_mm = 1.0;  // a marker's mean further than this from the surface is reported (mm)

  void Register(OptionFields* fields);
  bool Check() const;
};

struct RegisteredMarker {
  std::string name;
  SurfacePoint point;        // on the neutral
  Vec3 position = Vec3::Zero();  // x0(point) (mm, head space)
  Vec3 offset = Vec3::Zero();    // position - the package's marker point (mm)
  double sigma_mm = 0;       // uncertainty of the position (RMS spread over the frames / sqrt(frames))
  double motion_mm = 0;      // RMS tangential motion against the surface over the take (mm)
  double normal_mm = 0;      // signed distance of the mean from the surface (mm)
  int frames = 0;            // frames with a bundle
};

struct RegisterOutput {
  std::vector<Marker> markers;             // the day's markers (package order, found ones)
  std::vector<RegisteredMarker> registered;  // same order
  std::vector<std::string> not_found;      // not painted (or never seen)
  std::vector<std::string> loose;          // moving against the surface
  std::vector<std::string> off_surface;    // mean off the surface
  int frames = 0;
  int passes = 0;
  double pose_correction_mm = 0;  // how far step 3 moved the furthest marker (mm)
  int renamed = 0;                // dots whose tracked name the paint's prior changed (step 4)
  std::vector<std::string> warnings;
  std::string BriefReport() const;
};

struct RegisterInput {
  std::filesystem::path shot;
  std::filesystem::path calibration;
  std::filesystem::path actor;
  std::filesystem::path work;  // scratch folder (the passes' tracks and markers)
};

RegisterOutput RunRegister(const RegisterInput& input, const RegisterOptions& options);

// The report (docs/formats.md, "register report"): per marker its offset,
// uncertainty and motion; the markers not found, loose, off the surface.
std::string RegisterReportJson(const RegisterOutput& output);

// A picture of the neutral seen from the front with each marker's offset
// as an arrow (scaled `arrow_scale` x), red where reported.
void WriteOffsetPicture(const Actor& actor, const RegisterOutput& output,
                        const std::filesystem::path& png, double arrow_scale = 3);

}  // namespace hmc
