#include "core/render_mesh.h"

#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>
#include <spdlog/spdlog.h>

#include "core/error.h"
#include "core/parallel.h"
#include "core/raster.h"

namespace hmc {
namespace {

constexpr double kPi = 3.14159265358979323846;

double SrgbToLinear(double c) {
  return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
}
double LinearToSrgb(double c) {
  c = std::clamp(c, 0.0, 1.0);
  return c <= 0.0031308 ? 12.92 * c : 1.055 * std::pow(c, 1.0 / 2.4) - 0.055;
}
Eigen::Vector3d SrgbToLinear(const Eigen::Vector3d& c) {
  return {SrgbToLinear(c[0]), SrgbToLinear(c[1]), SrgbToLinear(c[2])};
}

// A light fixed to the camera (camera frame: x right, y down, z forward).
struct Light {
  Eigen::Vector3d toward;  // unit vector from the surface toward the light
  double intensity;
  double specular;         // Blinn-Phong weight
};

const Light kLights[] = {
    // Key: upper left, in front.
    {Eigen::Vector3d(-0.45, -0.55, -0.70).normalized(), 0.85, 0.10},
    // Fill: right, a little below, weaker and softer.
    {Eigen::Vector3d(0.75, 0.15, -0.65).normalized(), 0.30, 0.03},
};
constexpr double kAmbient = 0.10;
constexpr double kShininess = 40.0;

struct View {
  Mat3 cam_from_head;   // rotation
  Vec3 eye_in_head;     // camera centre (perspective)
  double scale = 1;     // px per mm (orthographic) or focal length (px)
  Vec2 offset{0, 0};    // principal point (px)
  bool perspective = true;
  double near = 0;      // nearest camera depth drawn (mm)

  Vec3 ToCamera(const Vec3& p_in_head) const {
    return cam_from_head * (p_in_head - eye_in_head);
  }
  Vec2 Project(const Vec3& p_in_cam) const {
    if (perspective) return scale * p_in_cam.head<2>() / p_in_cam.z() + offset;
    return scale * p_in_cam.head<2>() + offset;
  }
};

// Camera on an orbit around the box centre, framing the box's 8 corners in
// a width x height image with the margin left free.
View FrameBox(const Eigen::Matrix<double, 2, 3>& box,
              const MeshRenderOptions& options, int width, int height) {
  const Vec3 center = 0.5 * (box.row(0) + box.row(1)).transpose();
  const double radius =
      std::max(0.5 * (box.row(1) - box.row(0)).norm(), 1e-9);
  const double yaw = options.yaw_deg * kPi / 180.0;
  const double pitch = options.pitch_deg * kPi / 180.0;
  // head_from_orbit: the front view turned by yaw about +y, then pitched.
  const Mat3 orbit = (Eigen::AngleAxisd(yaw, Vec3::UnitY()) *
                      Eigen::AngleAxisd(-pitch, Vec3::UnitX()))
                         .toRotationMatrix();
  // Front camera: x_cam = x_head, y_cam = -y_head, z_cam = -z_head.
  const Mat3 front = Vec3(1, -1, -1).asDiagonal();
  View view;
  view.perspective = options.perspective;
  view.cam_from_head = front * orbit.transpose();
  const double distance = options.perspective ? options.distance * radius
                                              : 2.0 * radius;
  view.eye_in_head = center + distance * (orbit * Vec3::UnitZ());
  view.near = 0.01 * radius;

  Eigen::Vector2d lo(1e300, 1e300);
  Eigen::Vector2d hi(-1e300, -1e300);
  for (int corner = 0; corner < 8; ++corner) {
    const Vec3 p(box((corner >> 0) & 1, 0), box((corner >> 1) & 1, 1),
                 box((corner >> 2) & 1, 2));
    const Vec3 c = view.ToCamera(p);
    const Vec2 q = options.perspective ? Vec2(c.head<2>() / c.z())
                                       : Vec2(c.head<2>());
    lo = lo.cwiseMin(q);
    hi = hi.cwiseMax(q);
  }
  const double usable_w = width * (1.0 - 2.0 * options.margin);
  const double usable_h = height * (1.0 - 2.0 * options.margin);
  view.scale = std::min(usable_w / std::max(hi.x() - lo.x(), 1e-12),
                        usable_h / std::max(hi.y() - lo.y(), 1e-12));
  // Centre the framed box: pixel centres at integers.
  view.offset = Vec2(0.5 * (width - 1), 0.5 * (height - 1)) -
                view.scale * 0.5 * (lo + hi);
  return view;
}

cv::Mat Render(const TriMesh& mesh, const MeshRenderOptions& options,
               const MatX3d& albedo_linear) {
  if (!options.Check()) throw InputError("invalid mesh render options");
  const int s = options.supersample;
  const int width = options.width * s;
  const int height = options.height * s;
  const Eigen::Matrix<double, 2, 3> box =
      options.frame_box ? *options.frame_box
                        : (mesh.NumVertices() > 0
                               ? BoundingBox(mesh.V)
                               : Eigen::Matrix<double, 2, 3>::Zero());
  const View view = FrameBox(box, options, width, height);

  const int num_vertices = mesh.NumVertices();
  MatX3d screen(num_vertices, 3);
  MatX3d in_cam(num_vertices, 3);
  Eigen::VectorXd inv_w;
  if (options.perspective) inv_w.resize(num_vertices);
  const double near = view.near;
  for (int v = 0; v < num_vertices; ++v) {
    const Vec3 c = view.ToCamera(mesh.V.row(v).transpose());
    in_cam.row(v) = c.transpose();
    const Vec2 q = options.perspective && c.z() > near ? view.Project(c)
                   : options.perspective             ? Vec2(0, 0)
                                                     : view.Project(c);
    screen.row(v) << q.x(), q.y(), c.z();
    // Behind the near plane: a non-positive 1/w makes Rasterize skip every
    // triangle using the vertex (previews are not clipped).
    if (options.perspective) inv_w[v] = c.z() > near ? 1.0 / c.z() : -1.0;
  }
  RasterOptions raster;
  raster.width = width;
  raster.height = height;
  const RasterBuffer buffer = Rasterize(screen, inv_w, mesh.F, raster);

  const MatX3d normals = VertexNormals(mesh.V, mesh.F);
  const Eigen::Vector3d background = SrgbToLinear(options.background_rgb);
  const Eigen::Vector3d base = SrgbToLinear(options.base_rgb);
  const double wire_px = 0.8 * s;
  cv::Mat linear(height, width, CV_32FC3);
  ParallelFor(0, height, [&](int64_t y) {
    auto* row = linear.ptr<cv::Vec3f>(static_cast<int>(y));
    for (int x = 0; x < width; ++x) {
      const int index = buffer.Index(x, static_cast<int>(y));
      Eigen::Vector3d color = background;
      if (buffer.Covered(index)) {
        const int t = buffer.triangle[index];
        Vec3 n = view.cam_from_head *
                 InterpolateAt(buffer, index, mesh.F, normals).transpose();
        const Vec3 p = InterpolateAt(buffer, index, mesh.F, in_cam).transpose();
        const Vec3 to_eye =
            options.perspective ? Vec3(-p.normalized()) : Vec3(0, 0, -1);
        if (n.squaredNorm() < 1e-24) n = to_eye;
        n.normalize();
        if (n.dot(to_eye) < 0) n = -n;  // two-sided
        const Eigen::Vector3d albedo =
            albedo_linear.rows() > 0
                ? Eigen::Vector3d(
                      InterpolateAt(buffer, index, mesh.F, albedo_linear)
                          .transpose())
                : base;
        Eigen::Vector3d lit = kAmbient * albedo;
        for (const Light& light : kLights) {
          const double diffuse = std::max(0.0, n.dot(light.toward));
          const Vec3 half = (light.toward + to_eye).normalized();
          const double specular =
              diffuse > 0 ? light.specular *
                                std::pow(std::max(0.0, n.dot(half)), kShininess)
                          : 0.0;
          lit += light.intensity * (diffuse * albedo +
                                    Eigen::Vector3d::Constant(specular));
        }
        color = lit;
        if (options.wireframe) {
          double nearest = 1e300;
          for (int i = 0; i < 3; ++i) {
            const Vec2 a = screen.row(mesh.F(t, (i + 1) % 3)).head<2>();
            const Vec2 b = screen.row(mesh.F(t, (i + 2) % 3)).head<2>();
            const Vec2 e = b - a;
            const Vec2 d = Vec2(x, static_cast<double>(y)) - a;
            nearest = std::min(nearest, std::abs(e.x() * d.y() - e.y() * d.x()) /
                                            std::max(e.norm(), 1e-12));
          }
          if (nearest < wire_px) color *= 0.35;
        }
      }
      row[x] = cv::Vec3f(static_cast<float>(color[2]),
                         static_cast<float>(color[1]),
                         static_cast<float>(color[0]));
    }
  });
  // Box filter in linear light, then encode to sRGB.
  cv::Mat averaged;
  if (s > 1) {
    cv::resize(linear, averaged, cv::Size(options.width, options.height), 0, 0,
               cv::INTER_AREA);
  } else {
    averaged = linear;
  }
  cv::Mat image(options.height, options.width, CV_8UC3);
  for (int y = 0; y < image.rows; ++y) {
    const auto* in = averaged.ptr<cv::Vec3f>(y);
    auto* out = image.ptr<cv::Vec3b>(y);
    for (int x = 0; x < image.cols; ++x) {
      for (int c = 0; c < 3; ++c) {
        out[x][c] = cv::saturate_cast<uchar>(255.0 * LinearToSrgb(in[x][c]));
      }
    }
  }
  return image;
}

}  // namespace

bool MeshRenderOptions::Check() const {
  bool ok = true;
  const auto fail = [&](const char* what) {
    spdlog::error("mesh render options: {}", what);
    ok = false;
  };
  if (width < 1 || height < 1 || width > 16384 || height > 16384) {
    fail("width and height must be in [1, 16384] px");
  }
  if (supersample < 1 || supersample > 8) fail("supersample must be in [1, 8]");
  if (!(distance > 1.05 && std::isfinite(distance))) {
    fail("distance must be > 1.05 bounding-sphere radii");
  }
  if (!(margin >= 0 && margin < 0.45)) fail("margin must be in [0, 0.45)");
  if (!std::isfinite(yaw_deg) || !std::isfinite(pitch_deg)) {
    fail("yaw_deg and pitch_deg must be finite");
  }
  if (!(std::abs(pitch_deg) < 90)) fail("pitch_deg must be in (-90, 90)");
  return ok;
}

cv::Mat RenderMesh(const TriMesh& mesh, const MeshRenderOptions& options,
                   const MatX3d& vertex_rgb) {
  MatX3d albedo;
  if (vertex_rgb.rows() > 0) {
    HMC_CHECK(vertex_rgb.rows() == mesh.NumVertices());
    albedo = vertex_rgb.unaryExpr([](double c) { return SrgbToLinear(c); });
  }
  return Render(mesh, options, albedo);
}

cv::Mat RenderMeshScalars(const TriMesh& mesh, const Eigen::VectorXd& values,
                          double lo, double hi, ColorMap map,
                          const MeshRenderOptions& options) {
  HMC_CHECK(values.size() == mesh.NumVertices());
  return RenderMesh(mesh, options, MapScalars(values, lo, hi, map));
}

cv::Mat ComposeLabelledPanels(const std::vector<cv::Mat>& panels,
                              const std::vector<std::string>& labels) {
  HMC_CHECK(!panels.empty() && panels.size() == labels.size());
  constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;
  constexpr double kScale = 0.6;
  constexpr int kStrip = 30;
  std::vector<cv::Mat> columns;
  for (size_t i = 0; i < panels.size(); ++i) {
    HMC_CHECK(panels[i].type() == CV_8UC3 && panels[i].rows == panels[0].rows);
    cv::Mat strip(kStrip, panels[i].cols, CV_8UC3, cv::Scalar(28, 28, 28));
    int baseline = 0;
    const cv::Size size = cv::getTextSize(labels[i], kFont, kScale, 1, &baseline);
    cv::putText(strip, labels[i],
                cv::Point(std::max(2, (strip.cols - size.width) / 2),
                          (kStrip + size.height) / 2),
                kFont, kScale, cv::Scalar(235, 235, 235), 1, cv::LINE_AA);
    cv::Mat column;
    cv::vconcat(panels[i], strip, column);
    columns.push_back(column);
  }
  cv::Mat out;
  cv::hconcat(columns, out);
  return out;
}

}  // namespace hmc
