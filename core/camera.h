// The helmet camera: a lens model and its parameters. Every stage that
// projects or unprojects (calibration, undistortion, tracking,
// triangulation, the renderer of `hmc synth shot`) calls Camera::Project /
// Unproject and needs to know nothing else of the model (as basalt's
// generic_camera.hpp does with a variant):
//
//   kannala_brandt  Kannala-Brandt k1..k4, OpenCV's cv::fisheye
//                   (core/camera_fisheye.h)
//   pinhole_radtan  OpenCV's pinhole with k1, k2, p1, p2[, k3]
//                   (core/camera_radtan.h)
//   double_sphere   Usenko et al. 2018, xi and alpha
//                   (core/camera_double_sphere.h)
//
// The parameter array of the templated functions (Ceres Jets welcome) is
// fx, fy, cx, cy followed by the model's distortion parameters in the order
// above (FisheyeParam: kFx .. kCy, kK1 onwards). The files that hold these
// parameters are in docs/formats.md (calibration.yaml, Kalibr camchain).
#pragma once

#include <array>
#include <string>

#include <opencv2/core.hpp>

#include "core/camera_double_sphere.h"
#include "core/camera_fisheye.h"
#include "core/camera_radtan.h"
#include "core/types.h"

namespace hmc {

enum class CameraModel { kKannalaBrandt, kPinholeRadTan, kDoubleSphere };

// The calibration.yaml name of each model: kannala_brandt, pinhole_radtan,
// double_sphere.
const char* CameraModelName(CameraModel model);
// False if `name` is not one of them.
bool ParseCameraModel(const std::string& name, CameraModel* model);
// "kannala_brandt, pinhole_radtan, double_sphere", for error messages.
std::string CameraModelNames();

// The number of distortion parameters (4, 5, 2).
int NumDistortionParams(CameraModel model);

constexpr int kMaxDistortionParams = 5;
constexpr int kNumCameraParams = kK1 + kMaxDistortionParams;

struct Camera {
  CameraModel model = CameraModel::kKannalaBrandt;
  int width = 0;   // image size (px)
  int height = 0;
  double fx = 0;   // focal lengths (px)
  double fy = 0;
  double cx = 0;   // principal point (px)
  double cy = 0;
  // The model's distortion parameters (NumDistortionParams of them, the
  // rest 0): k1..k4 | k1, k2, p1, p2, k3 | xi, alpha.
  std::array<double, kMaxDistortionParams> k = {0, 0, 0, 0, 0};

  // Projects `point_in_cam` (3, camera frame: +z along the optical axis, +x
  // right, +y down) to `pixel` (2) through `model`. Returns false (pixel
  // untouched) outside the model's one-to-one domain. Not limited to the
  // image: see IsInImage. `intrinsics`: kNumCameraParams values (at least
  // kK1 + NumDistortionParams(model)). T may be a ceres::Jet.
  template <typename T>
  static bool Project(CameraModel model, const T* intrinsics, const T* point_in_cam, T* pixel);

  // Inverts Project: a unit bearing vector in the camera frame for `pixel`
  // (the project's own iterative or closed-form inverse, never OpenCV's
  // undistortion). False where no point of the domain images at `pixel`.
  static bool Unproject(CameraModel model, const double* intrinsics, const double* pixel,
                        double* bearing);

  bool Project(const Vec3& point_in_cam, Vec2* pixel) const;
  bool Unproject(const Vec2& pixel, Vec3* bearing) const;

  // Inside the image: pixel centres at integers, so [-0.5, width - 0.5).
  bool IsInImage(const Vec2& pixel) const;

  // The largest angle off axis (rad) of the model's one-to-one domain.
  double MaxTheta() const;

  // Intrinsics in FisheyeParam order (fx, fy, cx, cy, then k).
  std::array<double, kNumCameraParams> Params() const;
  void SetParams(const double* intrinsics);

  // OpenCV's 3 x 3 camera matrix, and the distortion parameters as an
  // NumDistortionParams x 1 matrix (cv::fisheye's D for Kannala-Brandt,
  // cv::projectPoints' distCoeffs for pinhole_radtan).
  cv::Matx33d K() const;
  cv::Mat D() const;

  // A camera of `model` from OpenCV's K (3 x 3, no skew) and D (a vector of
  // NumDistortionParams numbers; pinhole_radtan also takes 4, k3 = 0).
  // Throws InputError if the shapes are wrong, K has skew, a focal length
  // is not positive or a double-sphere parameter is out of its range.
  static Camera FromOpenCv(const cv::Mat& K, const cv::Mat& D, cv::Size size,
                           CameraModel model = CameraModel::kKannalaBrandt);

  // Throws InputError if a parameter is outside the model's range
  // (double sphere: alpha in [0, 1], xi > -1).
  void CheckModelParams() const;
};

// The name this type had while it held only Kannala-Brandt lenses.
using FisheyeCamera = Camera;

template <typename T>
bool Camera::Project(CameraModel model, const T* intrinsics, const T* point_in_cam, T* pixel) {
  switch (model) {
    case CameraModel::kKannalaBrandt:
      return KannalaBrandt::Project(intrinsics, point_in_cam, pixel);
    case CameraModel::kPinholeRadTan:
      return RadTan::Project(intrinsics, point_in_cam, pixel);
    case CameraModel::kDoubleSphere:
      return DoubleSphere::Project(intrinsics, point_in_cam, pixel);
  }
  return false;
}

}  // namespace hmc
