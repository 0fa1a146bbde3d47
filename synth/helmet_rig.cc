#include "synth/helmet_rig.h"

#include <cmath>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "core/error.h"

namespace hmc {

void HelmetRigOptions::Register(OptionFields* fields) {
  fields->SetGroup("rig");
  fields->Add("width", &width, "image width (px)").In(64, 8192);
  fields->Add("height", &height, "image height (px)").In(64, 8192);
  fields->Add("model", &model, "lens model: kannala_brandt | pinhole_radtan | double_sphere");
  fields->Add("focal_px", &focal_px,
              "focal length (px per radian of a fisheye, px per unit tangent of a pinhole)")
      .Above(10).Below(1e5);
  // Kannala-Brandt coefficients of real lenses are well inside [-1, 1]
  // (docs/calibration.md); beyond, the projection is no lens.
  fields->Add("k1", &k1, "Kannala-Brandt k1; pinhole_radtan radial k1").In(-1, 1);
  fields->Add("k2", &k2, "Kannala-Brandt k2; pinhole_radtan radial k2").In(-1, 1);
  fields->Add("k3", &k3, "Kannala-Brandt k3; pinhole_radtan radial k3").In(-1, 1);
  fields->Add("k4", &k4, "Kannala-Brandt k4").In(-1, 1);
  fields->Add("p1", &p1, "pinhole_radtan tangential p1").In(-0.1, 0.1);
  fields->Add("p2", &p2, "pinhole_radtan tangential p2").In(-0.1, 0.1);
  fields->Add("xi", &xi, "double_sphere xi").In(-0.99, 10);
  fields->Add("alpha", &alpha, "double_sphere alpha").In(0, 1);
  fields->Add("camera_distance", &camera_distance,
              "camera centre to the face surface along the axis (mm)")
      .In(50, 1000);
  fields->Add("upper_camera_y", &upper_camera_y, "upper camera height (mm, helmet space)")
      .In(-1000, 1000);
  fields->Add("lower_camera_y", &lower_camera_y, "lower camera height (mm, helmet space)")
      .In(-1000, 1000);
  fields->Add("tag_size", &tag_size, "tag edge at the black border (mm)").Above(2).Below(200);
  fields->SetGroup("");
}

bool HelmetRigOptions::Check() const {
  CHECK_OPTION_LIMITS();
  CameraModel lens;
  CHECK_OPTION(ParseCameraModel(model, &lens));
  // The lens must be one-to-one over the field a helmet camera sees (to 90
  // degrees off axis; a pinhole lens to 60).
  const double needed = lens == CameraModel::kPinholeRadTan ? M_PI / 3 : M_PI / 2;
  CHECK_OPTION(MakeCamera(*this).MaxTheta() >= needed);
  return true;
}

namespace {

// cam_from_helmet for a camera at `centre` looking along `forward` with
// helmet +y as "up" (image rows run down).
Rigid3 LookAt(const Vec3& centre, const Vec3& forward) {
  const Vec3 z = forward.normalized();
  const Vec3 x = z.cross(Vec3::UnitY()).normalized();
  const Vec3 y = z.cross(x);
  Mat3 helmet_from_cam_rotation;
  helmet_from_cam_rotation << x, y, z;
  Rigid3 helmet_from_cam = Rigid3::Identity();
  helmet_from_cam.linear() = helmet_from_cam_rotation;
  helmet_from_cam.translation() = centre;
  return helmet_from_cam.inverse();
}

// A tag at `centre` facing `target` (the tag's -z toward it), its columns
// along helmet +x as far as the facing allows.
Rigid3 TagPose(const Vec3& centre, const Vec3& target) {
  const Vec3 z = (centre - target).normalized();
  const Vec3 x = (Vec3::UnitX() - Vec3::UnitX().dot(z) * z).normalized();
  const Vec3 y = z.cross(x);
  Rigid3 pose = Rigid3::Identity();
  pose.linear() << x, y, z;
  pose.translation() = centre;
  return pose;
}

}  // namespace

Camera MakeCamera(const HelmetRigOptions& options) {
  Camera camera;
  if (!ParseCameraModel(options.model, &camera.model)) {
    throw InputError(fmt::format("rig.model '{}' is not a lens model ({})", options.model,
                                 CameraModelNames()));
  }
  camera.width = options.width;
  camera.height = options.height;
  camera.fx = options.focal_px;
  camera.fy = options.focal_px;
  camera.cx = (options.width - 1) / 2.0 + 3.7;  // a real lens is never centred
  camera.cy = (options.height - 1) / 2.0 - 2.9;
  switch (camera.model) {
    case CameraModel::kKannalaBrandt:
      camera.k = {options.k1, options.k2, options.k3, options.k4, 0};
      break;
    case CameraModel::kPinholeRadTan:
      camera.k = {options.k1, options.k2, options.p1, options.p2, options.k3};
      break;
    case CameraModel::kDoubleSphere:
      camera.k = {options.xi, options.alpha, 0, 0, 0};
      break;
  }
  return camera;
}

HelmetRig MakeHelmetRig(const HelmetRigOptions& options,
                        double face_front_z_upper, double face_front_z_lower) {
  HelmetRig rig;
  const Camera camera = MakeCamera(options);
  // Both cameras sit on one vertical boom at the upper camera's distance.
  const double boom_z = face_front_z_upper + options.camera_distance;
  const Vec3 upper(0, options.upper_camera_y, boom_z);
  const Vec3 lower(0, options.lower_camera_y,
                   std::max(boom_z, face_front_z_lower + options.camera_distance));
  // The upper camera looks slightly down at the face's middle, the lower one
  // up at it (the mouth and chin are its subject).
  const Vec3 upper_target(0, -25, 0);
  const Vec3 lower_target(0, -30, 0);
  HelmetCamera cam0{"cam0", camera, LookAt(upper, upper_target - upper)};
  HelmetCamera cam1{"cam1", camera, LookAt(lower, lower_target - lower)};
  // The second camera's lens is a little different, as in any real rig.
  cam1.camera.fx *= 1.004;
  cam1.camera.fy *= 1.004;
  cam1.camera.cx -= 5.1;
  cam1.camera.cy += 4.3;
  rig.cameras = {cam0, cam1};

  // Tags on the helmet frame beside the cheeks and on the brow band, facing
  // the boom so both cameras see them.
  const Vec3 boom_middle = 0.5 * (upper + lower);
  const double s = options.tag_size;
  const std::vector<Vec3> centres = {
      Vec3(-92, -38, face_front_z_upper - 40), Vec3(92, -38, face_front_z_upper - 40),
      Vec3(-50, 82, face_front_z_upper - 15), Vec3(50, 82, face_front_z_upper - 15)};
  for (size_t i = 0; i < centres.size(); ++i) {
    rig.tags.push_back({static_cast<int>(i), s, TagPose(centres[i], boom_middle)});
  }
  return rig;
}

}  // namespace hmc
