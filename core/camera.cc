#include "core/camera.h"

#include <cmath>

#include <fmt/format.h>

#include "core/error.h"

namespace hmc {

const char* CameraModelName(CameraModel model) {
  switch (model) {
    case CameraModel::kKannalaBrandt:
      return "kannala_brandt";
    case CameraModel::kPinholeRadTan:
      return "pinhole_radtan";
    case CameraModel::kDoubleSphere:
      return "double_sphere";
  }
  return "unknown";
}

bool ParseCameraModel(const std::string& name, CameraModel* model) {
  for (CameraModel m :
       {CameraModel::kKannalaBrandt, CameraModel::kPinholeRadTan, CameraModel::kDoubleSphere}) {
    if (name == CameraModelName(m)) {
      *model = m;
      return true;
    }
  }
  return false;
}

std::string CameraModelNames() { return "kannala_brandt, pinhole_radtan, double_sphere"; }

int NumDistortionParams(CameraModel model) {
  switch (model) {
    case CameraModel::kKannalaBrandt:
      return 4;
    case CameraModel::kPinholeRadTan:
      return RadTan::kNumRadTan;
    case CameraModel::kDoubleSphere:
      return DoubleSphere::kNumDoubleSphere;
  }
  return 0;
}

bool Camera::Unproject(CameraModel model, const double* intrinsics, const double* pixel,
                       double* bearing) {
  switch (model) {
    case CameraModel::kKannalaBrandt:
      return KannalaBrandt::Unproject(intrinsics, pixel, bearing);
    case CameraModel::kPinholeRadTan:
      return RadTan::Unproject(intrinsics, pixel, bearing);
    case CameraModel::kDoubleSphere:
      return DoubleSphere::Unproject(intrinsics, pixel, bearing);
  }
  return false;
}

bool Camera::Project(const Vec3& point_in_cam, Vec2* pixel) const {
  const auto params = Params();
  return Project(model, params.data(), point_in_cam.data(), pixel->data());
}

bool Camera::Unproject(const Vec2& pixel, Vec3* bearing) const {
  const auto params = Params();
  return Unproject(model, params.data(), pixel.data(), bearing->data());
}

bool Camera::IsInImage(const Vec2& pixel) const {
  return pixel.x() >= -0.5 && pixel.x() < width - 0.5 && pixel.y() >= -0.5 &&
         pixel.y() < height - 0.5;
}

double Camera::MaxTheta() const {
  switch (model) {
    case CameraModel::kKannalaBrandt:
      return KannalaBrandt::MaxTheta(k.data());
    case CameraModel::kPinholeRadTan:
      return RadTan::MaxTheta(k.data());
    case CameraModel::kDoubleSphere:
      return DoubleSphere::MaxTheta(k.data());
  }
  return 0;
}

std::array<double, kNumCameraParams> Camera::Params() const {
  std::array<double, kNumCameraParams> p;
  p[kFx] = fx;
  p[kFy] = fy;
  p[kCx] = cx;
  p[kCy] = cy;
  for (int i = 0; i < kMaxDistortionParams; ++i) p[kK1 + i] = k[i];
  return p;
}

void Camera::SetParams(const double* intrinsics) {
  fx = intrinsics[kFx];
  fy = intrinsics[kFy];
  cx = intrinsics[kCx];
  cy = intrinsics[kCy];
  for (int i = 0; i < NumDistortionParams(model); ++i) k[i] = intrinsics[kK1 + i];
}

cv::Matx33d Camera::K() const { return cv::Matx33d(fx, 0, cx, 0, fy, cy, 0, 0, 1); }

cv::Mat Camera::D() const {
  const int n = NumDistortionParams(model);
  cv::Mat d(n, 1, CV_64F);
  for (int i = 0; i < n; ++i) d.at<double>(i, 0) = k[i];
  return d;
}

void Camera::CheckModelParams() const {
  if (model == CameraModel::kDoubleSphere) {
    const double xi = k[DoubleSphere::kXi];
    const double alpha = k[DoubleSphere::kAlpha];
    if (!(alpha >= 0.0 && alpha <= 1.0) || !(xi > -1.0) || !std::isfinite(xi)) {
      throw InputError(fmt::format(
          "double_sphere needs alpha in [0, 1] and xi > -1, got xi {} alpha {}", xi, alpha));
    }
  }
  for (int i = 0; i < NumDistortionParams(model); ++i) {
    if (!std::isfinite(k[i])) {
      throw InputError(fmt::format("{} distortion parameter {} is not finite",
                                   CameraModelName(model), i + 1));
    }
  }
}

Camera Camera::FromOpenCv(const cv::Mat& K, const cv::Mat& D, cv::Size size, CameraModel model) {
  const char* what = model == CameraModel::kKannalaBrandt ? "fisheye" : CameraModelName(model);
  if (K.rows != 3 || K.cols != 3 || K.channels() != 1) {
    throw InputError(fmt::format("{} K must be 3 x 3, got {} x {}", what, K.rows, K.cols));
  }
  const int n = NumDistortionParams(model);
  // OpenCV's pinhole distCoeffs are 4 or 5 long (k3 = 0 when absent).
  const bool count_ok = static_cast<int>(D.total()) == n ||
                        (model == CameraModel::kPinholeRadTan && D.total() == 4);
  if (!count_ok || D.channels() != 1 || (D.rows != 1 && D.cols != 1)) {
    switch (model) {
      case CameraModel::kKannalaBrandt:
        throw InputError(fmt::format(
            "fisheye D must hold 4 coefficients (k1..k4), got {} x {}", D.rows, D.cols));
      case CameraModel::kPinholeRadTan:
        throw InputError(fmt::format(
            "pinhole_radtan D must hold 4 or 5 coefficients (k1, k2, p1, p2[, k3]), got {} x {}",
            D.rows, D.cols));
      case CameraModel::kDoubleSphere:
        throw InputError(fmt::format("double_sphere D must hold 2 numbers (xi, alpha), got {} x {}",
                                     D.rows, D.cols));
    }
  }
  cv::Mat k64;
  cv::Mat d64;
  K.convertTo(k64, CV_64F);
  D.reshape(1, static_cast<int>(D.total())).convertTo(d64, CV_64F);
  const auto at = [&](int r, int c) { return k64.at<double>(r, c); };
  if (at(0, 1) != 0.0 || at(1, 0) != 0.0 || at(2, 0) != 0.0 || at(2, 1) != 0.0 ||
      at(2, 2) != 1.0) {
    throw InputError(fmt::format("{} K must be [fx 0 cx; 0 fy cy; 0 0 1] (no skew)", what));
  }
  Camera camera;
  camera.model = model;
  camera.width = size.width;
  camera.height = size.height;
  camera.fx = at(0, 0);
  camera.fy = at(1, 1);
  camera.cx = at(0, 2);
  camera.cy = at(1, 2);
  for (int i = 0; i < static_cast<int>(D.total()); ++i) camera.k[i] = d64.at<double>(i, 0);
  if (!(camera.fx > 0 && camera.fy > 0)) {
    throw InputError(fmt::format("{} K has non-positive focal length (fx {}, fy {})", what,
                                 camera.fx, camera.fy));
  }
  camera.CheckModelParams();
  return camera;
}

}  // namespace hmc
