#include "core/calibration.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>
#include <opencv2/core/eigen.hpp>

#include "core/error.h"
#include "core/file_util.h"
#include "core/options.h"
#include "core/yaml_values.h"

namespace hmc {

std::vector<Vec3> HelmetTag::CornersInHelmet() const {
  const double h = size / 2;
  return {helmet_from_tag * Vec3(-h, h, 0), helmet_from_tag * Vec3(h, h, 0),
          helmet_from_tag * Vec3(h, -h, 0), helmet_from_tag * Vec3(-h, -h, 0)};
}

namespace {

cv::Mat ToCv(const Rigid3& transform) {
  cv::Mat out;
  const Eigen::Matrix4d m = transform.matrix();
  cv::eigen2cv(m, out);
  return out;
}

Rigid3 RigidFromCv(const cv::Mat& m, const std::filesystem::path& path,
                   const std::string& what) {
  if (m.rows != 4 || m.cols != 4) {
    ThrowInputError(path, 0, "{} must be a 4 x 4 matrix", what);
  }
  Eigen::Matrix4d e;
  cv::Mat md;
  m.convertTo(md, CV_64F);
  cv::cv2eigen(md, e);
  Rigid3 out = Rigid3::Identity();
  out.linear() = e.topLeftCorner<3, 3>();
  out.translation() = e.topRightCorner<3, 1>();
  const double orthogonality =
      (out.linear() * out.linear().transpose() - Mat3::Identity()).norm();
  if (!(orthogonality < 1e-6) || !(out.linear().determinant() > 0)) {
    ThrowInputError(path, 0,
                    "{} is not a rigid transform: its 3 x 3 part is not a rotation "
                    "(|R R^T - I| = {:.3g}, det {:.6g})",
                    what, orthogonality, out.linear().determinant());
  }
  if ((e.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).norm() > 1e-9) {
    ThrowInputError(path, 0, "{}: the last row must be 0 0 0 1", what);
  }
  return out;
}

}  // namespace

void WriteCalibration(const std::filesystem::path& path, const HelmetRig& rig) {
  cv::FileStorage fs(".yaml", cv::FileStorage::WRITE | cv::FileStorage::MEMORY);
  fs.writeComment(
      "hmc helmet rig: cameras (model kannala_brandt | pinhole_radtan | double_sphere, "
      "OpenCV K, D), cam_from_helmet 4x4 (mm), helmet tags (docs/formats.md)");
  fs << "units" << "mm";
  fs << "cameras" << "[";
  for (const HelmetCamera& c : rig.cameras) {
    fs << "{" << "name" << c.name << "model" << CameraModelName(c.camera.model)
       << "image_width" << c.camera.width << "image_height" << c.camera.height
       << "K" << cv::Mat(c.camera.K()) << "D" << c.camera.D()
       << "cam_from_helmet" << ToCv(c.cam_from_helmet) << "}";
  }
  fs << "]";
  fs << "tag_family" << rig.tag_family;
  fs << "tags" << "[";
  for (const HelmetTag& t : rig.tags) {
    cv::Mat corners(4, 3, CV_64F);
    const std::vector<Vec3> c = t.CornersInHelmet();
    for (int i = 0; i < 4; ++i) {
      for (int j = 0; j < 3; ++j) corners.at<double>(i, j) = c[i][j];
    }
    fs << "{" << "id" << t.id << "size" << t.size << "helmet_from_tag"
       << ToCv(t.helmet_from_tag) << "corners_in_helmet" << corners << "}";
  }
  fs << "]";
  WriteFileAtomic(path, fs.releaseAndGetString());
}

namespace {

using yaml_values::Integer;
using yaml_values::Number;
using yaml_values::Required;
using yaml_values::Text;

using yaml_values::kMaxImageSide;

// An `!!opencv-matrix` node (rows, cols, dt, data) as a rows x cols CV_64F
// matrix.
cv::Mat ReadMatrix(const YAML::Node& node, const std::string& what,
                   const std::filesystem::path& path) {
  if (!node.IsMap()) {
    ThrowInputError(path, node.Mark().line + 1, "'{}' must be a matrix (rows, cols, dt, data)",
                    what);
  }
  const int rows = Integer(Required(node, what, "rows", path), what + ".rows", 1, 16, path);
  const int cols = Integer(Required(node, what, "cols", path), what + ".cols", 1, 16, path);
  const std::string dt = Text(Required(node, what, "dt", path), what + ".dt", path);
  if (dt != "d" && dt != "f") {
    ThrowInputError(path, node["dt"].Mark().line + 1, "'{}.dt' must be d or f, not '{}'", what,
                    dt);
  }
  const std::vector<double> data = yaml_values::Numbers(
      Required(node, what, "data", path), static_cast<size_t>(rows * cols), what + ".data", path);
  cv::Mat m(rows, cols, CV_64F);
  for (int i = 0; i < rows * cols; ++i) m.at<double>(i / cols, i % cols) = data[i];
  return m;
}

}  // namespace

HelmetRig ReadCalibration(const std::filesystem::path& path) {
  // calibration.yaml is written by OpenCV's FileStorage (WriteCalibration)
  // but read with yaml-cpp: FileStorage's parser hangs on some malformed
  // text (found by fuzzing: docs/reliability.md), yaml-cpp gives line
  // numbers and refuses repeated keys (ParseYaml). OpenCV's `%YAML:1.0`
  // directive is not YAML 1.2: it is blanked, keeping the line numbers.
  std::string text = ReadFile(path);
  if (text.rfind("%YAML:", 0) == 0) text.erase(0, std::min(text.find('\n'), text.size()));
  const YAML::Node root = ParseYaml(text, path);
  if (!root.IsMap()) ThrowInputError(path, 0, "not a calibration file (a map of units, cameras, tags)");
  HelmetRig rig;
  const YAML::Node cameras = root["cameras"];
  if (!cameras || !cameras.IsSequence() || cameras.size() == 0) {
    ThrowInputError(path, 0, "missing 'cameras' sequence");
  }
  // Every key is checked by name, so an incomplete or inconsistent file is
  // refused with the file and the key ("cameras[1].cam_from_helmet").
  int index = 0;
  for (const YAML::Node& node : cameras) {
    const std::string where = fmt::format("cameras[{}]", index++);
    HelmetCamera c;
    c.name = Text(Required(node, where, "name", path), where + ".name", path);
    if (c.name.empty()) ThrowInputError(path, node.Mark().line + 1, "'{}.name' is empty", where);
    // Two cameras of one name would read the same footage (docs/reliability.md).
    for (size_t other = 0; other < rig.cameras.size(); ++other) {
      if (rig.cameras[other].name == c.name) {
        ThrowInputError(path, node.Mark().line + 1, "'{}.name' {} is also cameras[{}]'s name",
                        where, c.name, other);
      }
    }
    // The lens model is named, never guessed: a file written for another
    // model (a radial-tangential D of 4 numbers reads as 4 Kannala-Brandt
    // coefficients) would otherwise run silently wrong.
    const std::string model_name =
        Text(Required(node, where, "model", path), where + ".model", path);
    CameraModel model;
    if (!ParseCameraModel(model_name, &model)) {
      ThrowInputError(path, node["model"].Mark().line + 1,
                      "camera '{}' ('{}.model'): lens model '{}' is not supported (supported: "
                      "{})",
                      c.name, where, model_name, CameraModelNames());
    }
    const cv::Mat K = ReadMatrix(Required(node, where, "K", path), where + ".K", path);
    const cv::Mat D = ReadMatrix(Required(node, where, "D", path), where + ".D", path);
    const cv::Mat cam_from_helmet =
        ReadMatrix(Required(node, where, "cam_from_helmet", path), where + ".cam_from_helmet", path);
    const int w = Integer(Required(node, where, "image_width", path), where + ".image_width", 1,
                          kMaxImageSide, path);
    const int h = Integer(Required(node, where, "image_height", path), where + ".image_height", 1,
                          kMaxImageSide, path);
    try {
      c.camera = Camera::FromOpenCv(K, D, cv::Size(w, h), model);
    } catch (const InputError& e) {
      ThrowInputError(path, node.Mark().line + 1, "camera '{}' ('{}.K' / '{}.D', model {}): {}",
                      c.name, where, where, model_name, e.what());
    }
    if (!(c.camera.fx > 0 && c.camera.fy > 0) || !std::isfinite(c.camera.cx) ||
        !std::isfinite(c.camera.cy)) {
      ThrowInputError(path, 0, "'{}.K': focal lengths must be positive and finite", where);
    }
    c.cam_from_helmet = RigidFromCv(cam_from_helmet, path, "'" + where + ".cam_from_helmet'");
    rig.cameras.push_back(c);
  }
  const YAML::Node tags = root["tags"];
  if (tags && !tags.IsNull()) {
    if (!tags.IsSequence()) ThrowInputError(path, tags.Mark().line + 1, "'tags' must be a sequence");
    if (tags.size() > 0 || root["tag_family"]) {
      rig.tag_family = Text(Required(root, "calibration", "tag_family", path), "tag_family", path);
    }
    index = 0;
    for (const YAML::Node& node : tags) {
      const std::string where = fmt::format("tags[{}]", index++);
      HelmetTag t;
      t.id = Integer(Required(node, where, "id", path), where + ".id", 0, 1 << 20, path);
      t.size = Number(Required(node, where, "size", path), where + ".size", path);
      if (!(t.size > 0)) ThrowInputError(path, node.Mark().line + 1, "'{}.size' must be positive", where);
      t.helmet_from_tag = RigidFromCv(
          ReadMatrix(Required(node, where, "helmet_from_tag", path), where + ".helmet_from_tag", path),
          path, "'" + where + ".helmet_from_tag'");
      rig.tags.push_back(t);
    }
  }
  return rig;
}

}  // namespace hmc
