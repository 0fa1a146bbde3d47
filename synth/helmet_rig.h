// The stereo helmet-mounted camera rig of synthetic footage (`hmc synth
// shot`): two cameras (Kannala-Brandt fisheyes by default; any lens model of
// core/camera.h) stacked vertically on a boom in
// front of the face (the upper at nose level, the lower below the mouth) and
// AprilTags (tag36h11) fixed on the helmet frame, all rigid in helmet space.
//
// Helmet space is head space at rest (core/types.h: +x actor's left, +y up,
// +z forward); the head then slips and vibrates inside the helmet
// (synth/performance.h, head_from_helmet per frame). A camera frame is
// OpenCV's: +z along the optical axis, +x right, +y down in the image.
// calibration.yaml (docs/formats.md, "calibration.yaml"; core/calibration.h)
// stores the rig.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "core/calibration.h"
#include "core/options.h"
#include "core/types.h"

namespace hmc {

struct HelmetRigOptions {
  int width = 1280;             // image size (px)
  int height = 1024;
  std::string model = "kannala_brandt";  // lens model: kannala_brandt | pinhole_radtan | double_sphere
  double focal_px = 700;        // focal length (px per radian of a fisheye, px per unit tangent of a pinhole)
  double k1 = -0.012;           // Kannala-Brandt k1..k4; pinhole_radtan uses k1, k2, k3 (radial)
  double k2 = 0.0035;
  double k3 = -0.0009;
  double k4 = 0.0001;
  double p1 = 0;                // pinhole_radtan tangential p1, p2
  double p2 = 0;
  double xi = 0;                // double_sphere xi, alpha
  double alpha = 0.5;
  double camera_distance = 160;  // camera centre to the face surface along the axis (mm)
  double upper_camera_y = -18;   // upper camera height in helmet space (mm, nose level)
  double lower_camera_y = -78;   // lower camera height (mm, below the mouth)
  double tag_size = 22;          // tag edge at the black border (mm); the white border adds 1/8 per side

  void Register(OptionFields* fields);
  bool Check() const;
};

// The rig's lens (cam0's; cam1's differs a little, as in any real rig).
Camera MakeCamera(const HelmetRigOptions& options);

// The default rig around a face whose frontal surface (head space, at the
// cameras' heights) is at z = face_front_z_upper / face_front_z_lower (mm).
HelmetRig MakeHelmetRig(const HelmetRigOptions& options,
                        double face_front_z_upper, double face_front_z_lower);

}  // namespace hmc
