// The calibration of a stereo helmet-mounted camera rig: cameras (a lens
// model and its parameters, core/camera.h) with their poses in helmet space, and the AprilTags fixed
// on the helmet (calibration.yaml, docs/formats.md). Every stage that looks
// at pixels reads it from here: undistortion, tracking, tag calibration,
// triangulation (the synthetic rig of `hmc synth shot` writes the same file).
//
// Helmet space is head space at rest (core/types.h: +x actor's left, +y up,
// +z forward). A camera frame is OpenCV's: +z along the optical axis, +x
// right, +y down in the image.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "core/camera.h"
#include "core/types.h"

namespace hmc {

// One helmet tag: a flat square plate with the tag and its white border.
// Tag frame: origin at the tag centre, +x along the pattern's columns, +y
// along its rows (down the printed pattern), +z into the plate (the tag is
// seen from -z).
struct HelmetTag {
  int id = 0;              // tag36h11 code index
  double size = 0;         // edge of the black border square (mm)
  Rigid3 helmet_from_tag;  // pose of the tag frame in helmet space

  // The four black-border corners in helmet space, in the order the
  // AprilTag library reports them (tag coordinates (-1, 1), (1, 1), (1, -1),
  // (-1, -1) in units of size / 2).
  std::vector<Vec3> CornersInHelmet() const;
};

struct HelmetCamera {
  std::string name;        // "cam0" (upper), "cam1" (lower)
  Camera camera;
  Rigid3 cam_from_helmet;
};

struct HelmetRig {
  std::vector<HelmetCamera> cameras;
  std::vector<HelmetTag> tags;
  std::string tag_family = "tag36h11";

  // The cameras' names in order ("cam0", "cam1"): how the footage is found.
  std::vector<std::string> CameraNames() const {
    std::vector<std::string> names;
    for (const HelmetCamera& hc : cameras) names.push_back(hc.name);
    return names;
  }
};

// calibration.yaml as OpenCV FileStorage YAML. Read throws InputError naming
// the file on a missing or malformed entry.
void WriteCalibration(const std::filesystem::path& path, const HelmetRig& rig);
HelmetRig ReadCalibration(const std::filesystem::path& path);

}  // namespace hmc
