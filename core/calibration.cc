#include "core/calibration.h"

#include <opencv2/core/eigen.hpp>

#include "core/error.h"
#include "core/file_util.h"

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
    ThrowInputError(path, 0, "{} is not a rigid transform", what);
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

HelmetRig ReadCalibration(const std::filesystem::path& path) {
  const std::string text = ReadFile(path);
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
  for (const cv::FileNode& node : cameras) {
    HelmetCamera c;
    node["name"] >> c.name;
    cv::Mat K, D, cam_from_helmet;
    node["K"] >> K;
    node["D"] >> D;
    node["cam_from_helmet"] >> cam_from_helmet;
    const int width = static_cast<int>(node["image_width"]);
    const int height = static_cast<int>(node["image_height"]);
    if (K.empty() || D.empty() || width <= 0 || height <= 0) {
      ThrowInputError(path, 0, "camera '{}' needs K, D, image_width, image_height",
                      c.name);
    }
    c.camera = FisheyeCamera::FromOpenCv(K, D, cv::Size(width, height));
    c.cam_from_helmet =
        RigidFromCv(cam_from_helmet, path, "camera '" + c.name + "' cam_from_helmet");
    rig.cameras.push_back(c);
  }
  fs["tag_family"] >> rig.tag_family;
  for (const cv::FileNode& node : fs["tags"]) {
    HelmetTag t;
    t.id = static_cast<int>(node["id"]);
    t.size = static_cast<double>(node["size"]);
    cv::Mat pose;
    node["helmet_from_tag"] >> pose;
    if (!(t.size > 0)) ThrowInputError(path, 0, "tag {} needs a positive size", t.id);
    t.helmet_from_tag = RigidFromCv(pose, path, "tag helmet_from_tag");
    rig.tags.push_back(t);
  }
  return rig;
}

}  // namespace hmc
