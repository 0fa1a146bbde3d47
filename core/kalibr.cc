#include "core/kalibr.h"

#include <cmath>
#include <sstream>

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include "core/error.h"
#include "core/file_util.h"
#include "core/options.h"
#include "core/yaml_values.h"

namespace hmc {
namespace {

using yaml_values::Numbers;
using yaml_values::Required;
using yaml_values::Text;

constexpr double kMmPerMetre = 1000;
using yaml_values::kMaxImageSide;

// Kalibr's names of the lens models hmc has (core/camera.h).
struct KalibrModel {
  CameraModel model;
  const char* camera_model;
  const char* distortion_model;
};
constexpr KalibrModel kKalibrModels[] = {
    {CameraModel::kKannalaBrandt, "pinhole", "equidistant"},
    {CameraModel::kPinholeRadTan, "pinhole", "radtan"},
    {CameraModel::kDoubleSphere, "ds", "none"},
};

const KalibrModel* FindKalibrModel(const std::string& camera_model,
                                   const std::string& distortion_model) {
  for (const KalibrModel& m : kKalibrModels) {
    if (camera_model == m.camera_model && distortion_model == m.distortion_model) return &m;
  }
  return nullptr;
}

const KalibrModel& KalibrModelOf(CameraModel model) {
  for (const KalibrModel& m : kKalibrModels) {
    if (m.model == model) return m;
  }
  AbortOnInvariant("a Kalibr name for every lens model", __FILE__, __LINE__,
                   CameraModelName(model));
}

}  // namespace

std::vector<KalibrCamera> ReadKalibrCamchain(const std::filesystem::path& path) {
  const std::string text = ReadFile(path);
  const YAML::Node root = ParseYaml(text, path);
  if (!root.IsMap()) ThrowInputError(path, 0, "a Kalibr camchain is a map of cam0, cam1, ...");
  std::vector<KalibrCamera> chain;
  for (int n = 0;; ++n) {
    const std::string name = fmt::format("cam{}", n);
    const YAML::Node cam = root[name];
    if (!cam) break;
    if (!cam.IsMap()) ThrowInputError(path, cam.Mark().line + 1, "'{}' must be a map", name);
    KalibrCamera k;
    k.name = name;
    const std::string model = Text(Required(cam, name, "camera_model", path), name + ".camera_model", path);
    if (model != "pinhole" && model != "ds") {
      ThrowInputError(path, cam["camera_model"].Mark().line + 1,
                      "camera '{}': '{}.camera_model' is '{}', not supported (supported: "
                      "pinhole-equi, pinhole-radtan, ds-none)",
                      name, name, model);
    }
    const std::string distortion =
        Text(Required(cam, name, "distortion_model", path), name + ".distortion_model", path);
    const KalibrModel* kalibr = FindKalibrModel(model, distortion);
    if (!kalibr) {
      ThrowInputError(path, cam["distortion_model"].Mark().line + 1,
                      "camera '{}': '{}.distortion_model' is '{}': Kalibr model '{}-{}' is not "
                      "supported (supported: pinhole-equi, pinhole-radtan, ds-none)",
                      name, name, distortion, model, distortion);
    }
    k.camera.model = kalibr->model;
    // Kalibr's ds puts xi, alpha before the focal lengths.
    const size_t lead = kalibr->model == CameraModel::kDoubleSphere ? 2 : 0;
    const size_t coeffs = kalibr->model == CameraModel::kDoubleSphere ? 0 : 4;
    const auto all_intr =
        Numbers(Required(cam, name, "intrinsics", path), 4 + lead, name + ".intrinsics", path);
    const std::vector<double> intr(all_intr.begin() + lead, all_intr.end());
    const auto dist = Numbers(Required(cam, name, "distortion_coeffs", path), coeffs,
                              name + ".distortion_coeffs", path);
    const auto res = Numbers(Required(cam, name, "resolution", path), 2, name + ".resolution", path);
    if (!(intr[0] > 0 && intr[1] > 0)) {
      ThrowInputError(path, cam["intrinsics"].Mark().line + 1,
                      "'{}.intrinsics': focal lengths must be positive", name);
    }
    if (!(res[0] >= 1 && res[1] >= 1 && res[0] <= kMaxImageSide && res[1] <= kMaxImageSide) ||
        res[0] != std::floor(res[0]) || res[1] != std::floor(res[1])) {
      // Bounded before the conversion to int (found by fuzzing: 1e80).
      ThrowInputError(path, cam["resolution"].Mark().line + 1,
                      "'{}.resolution' must be two integers from 1 to {}", name, kMaxImageSide);
    }
    k.camera.width = static_cast<int>(res[0]);
    k.camera.height = static_cast<int>(res[1]);
    k.camera.fx = intr[0];
    k.camera.fy = intr[1];
    k.camera.cx = intr[2];
    k.camera.cy = intr[3];
    for (size_t i = 0; i < lead; ++i) k.camera.k[i] = all_intr[i];
    for (size_t i = 0; i < dist.size(); ++i) k.camera.k[i] = dist[i];
    try {
      k.camera.CheckModelParams();
    } catch (const InputError& e) {
      ThrowInputError(path, cam["intrinsics"].Mark().line + 1, "camera '{}': {}", name, e.what());
    }
    if (const YAML::Node t = cam["T_cn_cnm1"]) {
      const std::string key = name + ".T_cn_cnm1";
      if (!t.IsSequence() || t.size() != 4) {
        ThrowInputError(path, t.Mark().line + 1, "'{}' must be 4 rows of 4 numbers", key);
      }
      Eigen::Matrix4d m;
      for (int r = 0; r < 4; ++r) {
        const auto row = Numbers(t[r], 4, key, path);
        for (int c = 0; c < 4; ++c) m(r, c) = row[c];
      }
      const Mat3 R = m.topLeftCorner<3, 3>();
      if ((R * R.transpose() - Mat3::Identity()).norm() > 1e-6 || !(R.determinant() > 0)) {
        ThrowInputError(path, t.Mark().line + 1,
                        "'{}' is not a rigid transform: its 3 x 3 part is not a rotation", key);
      }
      if ((m.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).norm() > 1e-9) {
        ThrowInputError(path, t.Mark().line + 1, "'{}': the last row must be 0 0 0 1", key);
      }
      if (n == 0) ThrowInputError(path, t.Mark().line + 1, "'{}': cam0 has no previous camera", key);
      k.has_cam_from_previous = true;
      k.cam_from_previous.linear() = R;
      k.cam_from_previous.translation() = kMmPerMetre * m.topRightCorner<3, 1>();
    } else if (n > 0) {
      ThrowInputError(path, cam.Mark().line + 1, "missing key '{}.T_cn_cnm1'", name);
    }
    chain.push_back(k);
  }
  if (chain.empty()) ThrowInputError(path, 0, "missing key 'cam0'");
  return chain;
}

void WriteKalibrCamchain(const std::filesystem::path& path, const HelmetRig& rig) {
  YAML::Emitter out;
  out.SetDoublePrecision(17);
  out << YAML::Comment("Kalibr camchain written by hmc (docs/formats.md, \"Kalibr camchain\")");
  out << YAML::BeginMap;
  for (size_t n = 0; n < rig.cameras.size(); ++n) {
    const HelmetCamera& hc = rig.cameras[n];
    const Camera& c = hc.camera;
    const KalibrModel& kalibr = KalibrModelOf(c.model);
    if (c.model == CameraModel::kPinholeRadTan && c.k[RadTan::kRadTanK3] != 0) {
      ThrowInputError(path, 0,
                      "camera '{}': Kalibr's radtan has 4 coefficients (k1, k2, p1, p2) and this "
                      "lens has k3 = {}",
                      hc.name, c.k[RadTan::kRadTanK3]);
    }
    out << YAML::Key << fmt::format("cam{}", n) << YAML::Value << YAML::BeginMap;
    out << YAML::Key << "camera_model" << YAML::Value << kalibr.camera_model;
    out << YAML::Key << "distortion_model" << YAML::Value << kalibr.distortion_model;
    out << YAML::Key << "intrinsics" << YAML::Value << YAML::Flow << YAML::BeginSeq;
    if (c.model == CameraModel::kDoubleSphere) {
      out << c.k[DoubleSphere::kXi] << c.k[DoubleSphere::kAlpha];
    }
    out << c.fx << c.fy << c.cx << c.cy << YAML::EndSeq;
    out << YAML::Key << "distortion_coeffs" << YAML::Value << YAML::Flow << YAML::BeginSeq;
    if (c.model != CameraModel::kDoubleSphere) {
      for (int i = 0; i < 4; ++i) out << c.k[i];
    }
    out << YAML::EndSeq;
    out << YAML::Key << "resolution" << YAML::Value << YAML::Flow << YAML::BeginSeq << c.width
        << c.height << YAML::EndSeq;
    out << YAML::Key << "rostopic" << YAML::Value << "/" + hc.name + "/image_raw";
    if (n > 0) {
      const Rigid3 t = hc.cam_from_helmet * rig.cameras[n - 1].cam_from_helmet.inverse();
      Eigen::Matrix4d m = t.matrix();
      m.topRightCorner<3, 1>() /= kMmPerMetre;
      out << YAML::Key << "T_cn_cnm1" << YAML::Value << YAML::BeginSeq;
      for (int r = 0; r < 4; ++r) {
        out << YAML::Flow << YAML::BeginSeq;
        for (int col = 0; col < 4; ++col) out << m(r, col);
        out << YAML::EndSeq;
      }
      out << YAML::EndSeq;
    }
    out << YAML::EndMap;
  }
  out << YAML::EndMap;
  WriteFileAtomic(path, std::string(out.c_str()) + "\n");
}

HelmetRig ApplyKalibr(const HelmetRig& rig, const std::vector<KalibrCamera>& chain,
                      const std::filesystem::path& origin) {
  if (chain.size() != rig.cameras.size()) {
    ThrowInputError(origin, 0, "the camchain has {} cameras, the calibration {}", chain.size(),
                    rig.cameras.size());
  }
  HelmetRig out = rig;
  for (size_t n = 0; n < chain.size(); ++n) {
    out.cameras[n].camera = chain[n].camera;
    if (chain[n].has_cam_from_previous) {
      out.cameras[n].cam_from_helmet =
          chain[n].cam_from_previous * out.cameras[n - 1].cam_from_helmet;
    }
  }
  return out;
}

}  // namespace hmc
