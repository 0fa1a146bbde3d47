// Kalibr camera chains (camchain.yaml, the output of Kalibr's
// kalibr_calibrate_cameras; https://github.com/ethz-asl/kalibr/wiki/yaml-formats),
// which many studios use for the helmet cameras' intrinsics:
//
//   cam0:
//     camera_model: pinhole
//     distortion_model: equidistant      # = Kannala-Brandt k1..k4 (cv::fisheye)
//     intrinsics: [fu, fv, pu, pv]       # px
//     distortion_coeffs: [k1, k2, k3, k4]
//     resolution: [width, height]        # px
//   cam1:
//     ...
//     T_cn_cnm1: 4 x 4 list of rows      # cam1_from_cam0, metres (Kalibr's unit)
//
// The lens models hmc has (core/camera.h), in Kalibr's names:
//   pinhole-equi    camera_model pinhole, distortion_model equidistant
//                   (kannala_brandt; coefficients k1..k4)
//   pinhole-radtan  camera_model pinhole, distortion_model radtan
//                   (pinhole_radtan; coefficients k1, k2, p1, p2; no k3)
//   ds-none         camera_model ds, distortion_model none, intrinsics
//                   [xi, alpha, fu, fv, pu, pv], distortion_coeffs []
//                   (double_sphere)
// Other models are refused. Pixel centres: Kalibr follows OpenCV (centre of
// the top-left pixel at (0, 0)), as hmc does.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "core/calibration.h"

namespace hmc {

struct KalibrCamera {
  std::string name;          // cam0, cam1, ... (the file's keys, in order)
  Camera camera;
  bool has_cam_from_previous = false;
  Rigid3 cam_from_previous = Rigid3::Identity();  // T_cn_cnm1 (mm here)
};

// Throws InputError naming the file and the key (cam1.T_cn_cnm1, ...) on a
// missing or malformed entry, an unsupported model, a non-rotation or a
// resolution that is not positive.
std::vector<KalibrCamera> ReadKalibrCamchain(const std::filesystem::path& path);

// Writes the cameras of `rig` (in order, cam_from_previous from their
// cam_from_helmet) atomically. Throws InputError (naming the camera) for a
// pinhole_radtan lens with k3 != 0, which Kalibr's radtan cannot hold.
void WriteKalibrCamchain(const std::filesystem::path& path, const HelmetRig& rig);

// `rig` with the intrinsics of the chain (by order; the counts must match)
// and, where the chain has T_cn_cnm1, camera n re-posed as
// T_cn_cnm1 * cam_{n-1}_from_helmet. Throws InputError (naming `origin`) if
// the number of cameras differs.
HelmetRig ApplyKalibr(const HelmetRig& rig, const std::vector<KalibrCamera>& chain,
                      const std::filesystem::path& origin);

}  // namespace hmc
