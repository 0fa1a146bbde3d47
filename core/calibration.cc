#include "core/calibration.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>
#include <opencv2/core/eigen.hpp>

#include "core/error.h"
#include "core/file_util.h"
#include "core/options.h"

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
      "hmc helmet rig: Kannala-Brandt fisheye cameras (OpenCV cv::fisheye K, "
      "D), cam_from_helmet 4x4 (mm), helmet tags (docs/formats.md)");
  fs << "units" << "mm";
  fs << "cameras" << "[";
  for (const HelmetCamera& c : rig.cameras) {
    fs << "{" << "name" << c.name << "model" << "kannala_brandt"
       << "image_width" << c.camera.width << "image_height" << c.camera.height
       << "K" << cv::Mat(c.camera.K()) << "D" << cv::Mat(c.camera.D())
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

HelmetRig ReadCalibrationFileStorage(const std::filesystem::path& path);

}  // namespace

HelmetRig ReadCalibration(const std::filesystem::path& path) {
  // OpenCV throws on malformed nodes (an `!!opencv-matrix` without `dt`,
  // found by fuzzing: docs/reliability.md); that is bad input, not a crash.
  try {
    return ReadCalibrationFileStorage(path);
  } catch (const cv::Exception& e) {
    ThrowInputError(path, 0, "not a valid calibration file: {}", e.err);
  }
}

namespace {

HelmetRig ReadCalibrationFileStorage(const std::filesystem::path& path) {
  const std::string text = ReadFile(path);
  {
    // A key given twice is refused like in every YAML hmc reads
    // (docs/reliability.md): yaml-cpp sees the text once OpenCV's
    // `%YAML:1.0` directive is blanked (line numbers kept); text it cannot
    // parse is left to FileStorage's own errors.
    std::string yaml = text;
    if (yaml.rfind("%YAML:", 0) == 0) yaml.erase(0, std::min(yaml.find('\n'), yaml.size()));
    bool parsed = true;
    try {
      YAML::Load(yaml);
    } catch (const YAML::Exception&) {
      parsed = false;
    }
    if (parsed) ParseYaml(yaml, path);
  }
  cv::FileStorage fs;
  try {
    fs.open(text, cv::FileStorage::READ | cv::FileStorage::MEMORY);
  } catch (const cv::Exception& e) {
    ThrowInputError(path, 0, "not an OpenCV FileStorage file: {}", e.what());
  }
  if (!fs.isOpened()) ThrowInputError(path, 0, "cannot parse as FileStorage YAML");
  HelmetRig rig;
  const cv::FileNode cameras = fs["cameras"];
  if (!cameras.isSeq() || cameras.size() == 0) {
    ThrowInputError(path, 0, "missing 'cameras' sequence");
  }
  // Every key is checked by name, so an incomplete or inconsistent file is
  // refused with the file and the key ("cameras[1].cam_from_helmet").
  int index = 0;
  for (const cv::FileNode& node : cameras) {
    const std::string where = fmt::format("cameras[{}]", index++);
    auto require = [&](const cv::FileNode& n, const char* key) {
      if (n[key].empty()) ThrowInputError(path, 0, "missing key '{}.{}'", where, key);
      return n[key];
    };
    HelmetCamera c;
    require(node, "name") >> c.name;
    if (c.name.empty()) ThrowInputError(path, 0, "'{}.name' is empty", where);
    cv::Mat K, D, cam_from_helmet;
    require(node, "K") >> K;
    require(node, "D") >> D;
    require(node, "cam_from_helmet") >> cam_from_helmet;
    const cv::FileNode w = require(node, "image_width"), h = require(node, "image_height");
    if (!w.isInt() || !h.isInt() || static_cast<int>(w) <= 0 || static_cast<int>(h) <= 0) {
      ThrowInputError(path, 0, "'{}.image_width' and '.image_height' must be positive integers",
                      where);
    }
    try {
      c.camera = FisheyeCamera::FromOpenCv(K, D, cv::Size(static_cast<int>(w), static_cast<int>(h)));
    } catch (const InputError& e) {
      ThrowInputError(path, 0, "'{}.K' / '{}.D': {}", where, where, e.what());
    }
    if (!(c.camera.fx > 0 && c.camera.fy > 0) || !std::isfinite(c.camera.cx) ||
        !std::isfinite(c.camera.cy)) {
      ThrowInputError(path, 0, "'{}.K': focal lengths must be positive and finite", where);
    }
    c.cam_from_helmet = RigidFromCv(cam_from_helmet, path, "'" + where + ".cam_from_helmet'");
    rig.cameras.push_back(c);
  }
  const cv::FileNode tags = fs["tags"];
  if (!tags.empty()) {
    if (fs["tag_family"].empty()) ThrowInputError(path, 0, "missing key 'tag_family'");
    fs["tag_family"] >> rig.tag_family;
  }
  index = 0;
  for (const cv::FileNode& node : tags) {
    const std::string where = fmt::format("tags[{}]", index++);
    for (const char* key : {"id", "size", "helmet_from_tag"}) {
      if (node[key].empty()) ThrowInputError(path, 0, "missing key '{}.{}'", where, key);
    }
    HelmetTag t;
    t.id = static_cast<int>(node["id"]);
    t.size = static_cast<double>(node["size"]);
    cv::Mat pose;
    node["helmet_from_tag"] >> pose;
    if (!(t.size > 0)) ThrowInputError(path, 0, "'{}.size' must be positive", where);
    t.helmet_from_tag = RigidFromCv(pose, path, "'" + where + ".helmet_from_tag'");
    rig.tags.push_back(t);
  }
  return rig;
}

}  // namespace

}  // namespace hmc
