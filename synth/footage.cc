#include "synth/footage.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <opencv2/imgproc.hpp>
#include <spdlog/spdlog.h>

#include "core/error.h"
#include "core/parallel.h"
#include "core/raster.h"
#include "synth/sensor_noise.h"
#include "synth/synth_random.h"

namespace hmc {

void FootageRenderOptions::Register(OptionFields* fields) {
  fields->SetGroup("render");
  fields->Add("dot_radius", &dot_radius, "painted dot radius on the skin (mm)");
  fields->Add("dot_albedo", &dot_albedo, "reflectance of the dot paint");
  fields->Add("skin_albedo", &skin_albedo, "mean skin reflectance");
  fields->Add("albedo_variation", &albedo_variation,
              "relative amplitude of the skin's albedo variation");
  fields->Add("tag_white", &tag_white, "reflectance of the tags' white");
  fields->Add("tag_black", &tag_black, "reflectance of the tags' black");
  fields->Add("background", &background, "radiance where nothing is hit");
  fields->Add("ambient", &ambient, "ambient light (fraction of full exposure)");
  fields->Add("light_power", &light_power,
              "each head light's irradiance at 170 mm, head-on (fraction of full exposure)");
  fields->Add("light_offset", &light_offset, "head light offset beside each camera (mm)");
  fields->Add("exposure", &exposure, "gain on the radiance before the sensor (1 = as lit)");
  fields->Add("exposure_drift", &exposure_drift,
              "relative change of the exposure from the first frame to the last (linear; -0.2 = "
              "20% darker at the end)");
  fields->Add("specular", &specular,
              "skin's specular (Blinn-Phong) reflectance (0 = matte; the dots' paint stays matte)");
  fields->Add("shininess", &shininess, "Blinn-Phong exponent of the skin's highlights");
  fields->Add("vignetting", &vignetting, "darkening at the image corner (0 = off)");
  fields->Add("read_noise", &read_noise, "std of the sensor read noise (8-bit levels; 0 = off)");
  fields->Add("shot_noise", &shot_noise, "shot-noise variance per level of signal (0 = off)");
  fields->Add("motion_blur_samples", &motion_blur_samples,
              "sub-frame samples over the shutter (1 = off)");
  fields->Add("shutter", &shutter, "exposure as a fraction of the frame interval");
  fields->Add("defocus_px", &defocus_px, "Gaussian defocus blur sigma (px; 0 = off)");
  fields->Add("max_edge_error_px", &max_edge_error_px, "fisheye subdivision tolerance (px)");
  fields->Add("transfer", &transfer,
              "8-bit encoding: linear | srgb (the sRGB curve, as most cameras write PNG)");
  fields->SetGroup("");
}

bool FootageRenderOptions::Check() const {
  bool ok = true;
  auto fail = [&](const std::string& message) {
    spdlog::error("render options: {}", message);
    ok = false;
  };
  auto unit = [](double x) { return x >= 0 && x <= 1; };
  if (!(dot_radius > 0.1 && dot_radius < 20)) fail("dot_radius must be in (0.1, 20) mm");
  if (!unit(dot_albedo) || !unit(skin_albedo) || !unit(tag_white) || !unit(tag_black) ||
      !unit(background)) {
    fail("reflectances and background must be in [0, 1]");
  }
  if (!(albedo_variation >= 0 && albedo_variation < 1)) fail("albedo_variation must be in [0, 1)");
  if (!(ambient >= 0 && ambient <= 2) || !(light_power >= 0 && light_power <= 10)) {
    fail("ambient must be in [0, 2] and light_power in [0, 10]");
  }
  if (!(light_offset >= 0 && light_offset < 200)) fail("light_offset must be in [0, 200) mm");
  if (!(exposure > 0 && exposure <= 10)) fail("exposure must be in (0, 10]");
  if (!(exposure_drift > -1 && exposure_drift <= 10)) fail("exposure_drift must be in (-1, 10]");
  if (!unit(specular)) fail("specular must be in [0, 1]");
  if (!(shininess >= 1 && shininess <= 1000)) fail("shininess must be in [1, 1000]");
  if (!unit(vignetting)) fail("vignetting must be in [0, 1]");
  if (!(read_noise >= 0 && read_noise < 50) || !(shot_noise >= 0 && shot_noise < 10)) {
    fail("read_noise must be in [0, 50) and shot_noise in [0, 10)");
  }
  if (motion_blur_samples < 1 || motion_blur_samples > 64) {
    fail("motion_blur_samples must be in [1, 64]");
  }
  if (!(shutter > 0 && shutter <= 1)) fail("shutter must be in (0, 1]");
  if (!(defocus_px >= 0 && defocus_px < 20)) fail("defocus_px must be in [0, 20)");
  if (transfer != "linear" && transfer != "srgb") fail("transfer must be linear or srgb");
  if (!(max_edge_error_px > 0.001 && max_edge_error_px <= 2)) {
    fail("max_edge_error_px must be in (0.001, 2]");
  }
  return ok;
}

void FootageRenderOptions::SetClean() {
  vignetting = 0;
  read_noise = 0;
  shot_noise = 0;
  motion_blur_samples = 1;
  defocus_px = 0;
}

double FootageRenderOptions::ExposureAt(double shot_fraction) const {
  return exposure * (1 + exposure_drift * shot_fraction);
}

namespace {

// Ray (origin 0, direction d) against the plane of triangle (p0, p1, p2)
// (Moller & Trumbore 1997, without the inside test): distance along d and
// barycentrics. Returns false if the ray is parallel to the plane.
inline bool IntersectPlane(const Vec3& d, const Vec3& p0, const Vec3& p1, const Vec3& p2,
                           double* dist, Vec3* bary) {
  const Vec3 e1 = p1 - p0;
  const Vec3 e2 = p2 - p0;
  const Vec3 pvec = d.cross(e2);
  const double det = e1.dot(pvec);
  if (std::abs(det) < 1e-300) return false;
  const double inv = 1.0 / det;
  const Vec3 tvec = -p0;
  const double u = tvec.dot(pvec) * inv;
  const Vec3 qvec = tvec.cross(e1);
  const double v = d.dot(qvec) * inv;
  *dist = e2.dot(qvec) * inv;
  *bary = Vec3(1 - u - v, u, v);
  return true;
}

// Reference distance of the head lights' irradiance (mm).
constexpr double kLightReferenceMm = 170.0;

}  // namespace

FootageRenderer::FootageRenderer(const TriMesh& neutral, const MatX2d& st,
                                 const std::vector<Marker>& markers, const HelmetRig& rig,
                                 const FootageRenderOptions& options, uint64_t seed)
    : rig_(rig), options_(options), F_(neutral.F), st_(st), markers_(markers) {
  HMC_CHECK(st.rows() == neutral.NumVertices());
  HMC_CHECK(options.Check());
  const int num_vertices = neutral.NumVertices();
  vertex_faces_.resize(num_vertices);
  for (int f = 0; f < F_.rows(); ++f) {
    for (int i = 0; i < 3; ++i) vertex_faces_[F_(f, i)].push_back(f);
  }
  for (const HelmetTag& tag : rig_.tags) patterns_.emplace_back(tag.id);
  const Vec2 lo = st.colwise().minCoeff().transpose();
  const Vec2 hi = st.colwise().maxCoeff().transpose();
  IndexDots(neutral, lo, hi);
  IndexTriangles(lo, hi);
  MakeAlbedoTexture(seed, lo, hi);
  PrecomputeRays();
}

// Dots: face-plane centres and skin metrics, binned by grid cell.
void FootageRenderer::IndexDots(const TriMesh& neutral, const Vec2& lo, const Vec2& hi) {
  const MatX2d& st = st_;
  const std::vector<Marker>& markers = markers_;
  const FootageRenderOptions& options = options_;
  grid_origin_ = lo - Vec2::Constant(cell_);
  grid_w_ = static_cast<int>((hi.x() - grid_origin_.x()) / cell_) + 2;
  grid_h_ = static_cast<int>((hi.y() - grid_origin_.y()) / cell_) + 2;
  dot_grid_.resize(static_cast<size_t>(grid_w_) * grid_h_);
  for (size_t m = 0; m < markers.size(); ++m) {
    const SurfacePoint& sp = markers[m].point;
    Vec2 c = Vec2::Zero();
    Eigen::Matrix2d metric = Eigen::Matrix2d::Identity();
    if (sp.face >= 0 && sp.face < F_.rows()) {
      for (int i = 0; i < 3; ++i) c += sp.bary[i] * st.row(F_(sp.face, i)).transpose();
      // The linear map st -> neutral surface on the marker's triangle,
      // M = E S^-1 (3 x 2), and its metric M^T M: a circle of the skin
      // around the marker is an ellipse in st.
      const int i0 = F_(sp.face, 0), i1 = F_(sp.face, 1), i2 = F_(sp.face, 2);
      Eigen::Matrix<double, 3, 2> E;
      E.col(0) = (neutral.V.row(i1) - neutral.V.row(i0)).transpose();
      E.col(1) = (neutral.V.row(i2) - neutral.V.row(i0)).transpose();
      Eigen::Matrix2d S;
      S.col(0) = (st.row(i1) - st.row(i0)).transpose();
      S.col(1) = (st.row(i2) - st.row(i0)).transpose();
      if (std::abs(S.determinant()) > 1e-12) {
        const Eigen::Matrix<double, 3, 2> M = E * S.inverse();
        metric = M.transpose() * M;
      }
    }
    dot_st_.push_back(c);
    dot_metric_.push_back(metric);
    if (sp.face < 0 || sp.face >= F_.rows()) continue;
    // Radius + anti-aliasing margin on the skin, in st along the most
    // stretched direction.
    const double lambda_min =
        std::max(Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(metric).eigenvalues()[0], 1e-2);
    const double reach = (options.dot_radius + 3.0) / std::sqrt(lambda_min);
    const int x0 = static_cast<int>((c.x() - reach - grid_origin_.x()) / cell_);
    const int x1 = static_cast<int>((c.x() + reach - grid_origin_.x()) / cell_);
    const int y0 = static_cast<int>((c.y() - reach - grid_origin_.y()) / cell_);
    const int y1 = static_cast<int>((c.y() + reach - grid_origin_.y()) / cell_);
    for (int y = std::max(0, y0); y <= std::min(grid_h_ - 1, y1); ++y) {
      for (int x = std::max(0, x0); x <= std::min(grid_w_ - 1, x1); ++x) {
        dot_grid_[y * grid_w_ + x].push_back(static_cast<int>(m));
      }
    }
  }
}

// Triangles by face-plane cell, for LocateFacePlane.
void FootageRenderer::IndexTriangles(const Vec2& lo, const Vec2& hi) {
  const MatX2d& st = st_;
  tri_origin_ = lo - Vec2::Constant(tri_cell_);
  tri_w_ = static_cast<int>((hi.x() - tri_origin_.x()) / tri_cell_) + 2;
  tri_h_ = static_cast<int>((hi.y() - tri_origin_.y()) / tri_cell_) + 2;
  tri_grid_.resize(static_cast<size_t>(tri_w_) * tri_h_);
  for (int f = 0; f < F_.rows(); ++f) {
    Vec2 a = st.row(F_(f, 0)).transpose(), b = a;
    for (int i = 1; i < 3; ++i) {
      a = a.cwiseMin(st.row(F_(f, i)).transpose());
      b = b.cwiseMax(st.row(F_(f, i)).transpose());
    }
    const int x0 = static_cast<int>((a.x() - tri_origin_.x()) / tri_cell_);
    const int x1 = static_cast<int>((b.x() - tri_origin_.x()) / tri_cell_);
    const int y0 = static_cast<int>((a.y() - tri_origin_.y()) / tri_cell_);
    const int y1 = static_cast<int>((b.y() - tri_origin_.y()) / tri_cell_);
    for (int y = std::max(0, y0); y <= std::min(tri_h_ - 1, y1); ++y) {
      for (int x = std::max(0, x0); x <= std::min(tri_w_ - 1, x1); ++x) {
        tri_grid_[y * tri_w_ + x].push_back(f);
      }
    }
  }
}

void FootageRenderer::MakeAlbedoTexture(uint64_t seed, const Vec2& lo, const Vec2& hi) {
  // Skin albedo variation: smooth random fields at 6 mm and 1.5 mm, upsampled
  // bicubically to the texture, zero mean, in [-1, 1].
  texture_origin_ = lo - Vec2::Constant(2.0);
  const int tw = static_cast<int>((hi.x() - lo.x() + 4.0) / texel_) + 2;
  const int th = static_cast<int>((hi.y() - lo.y() + 4.0) / texel_) + 2;
  SynthRandom rng = SynthRandom::Stream(seed, 60);
  cv::Mat field = cv::Mat::zeros(th, tw, CV_32F);
  for (const auto& [spacing, weight] : {std::pair{6.0, 0.75}, std::pair{1.5, 0.25}}) {
    const int cw = static_cast<int>(tw * texel_ / spacing) + 2;
    const int ch = static_cast<int>(th * texel_ / spacing) + 2;
    cv::Mat coarse(ch, cw, CV_32F);
    for (int y = 0; y < ch; ++y) {
      for (int x = 0; x < cw; ++x) coarse.at<float>(y, x) = static_cast<float>(rng.Uniform(-1, 1));
    }
    cv::Mat fine;
    cv::resize(coarse, fine, cv::Size(tw, th), 0, 0, cv::INTER_CUBIC);
    field += weight * fine;
  }
  albedo_texture_ = field;
}

void FootageRenderer::PrecomputeRays() {
  // Per camera: the exact ray of every pixel centre and the vignetting.
  for (const HelmetCamera& hc : rig_.cameras) {
    const FisheyeCamera& cam = hc.camera;
    std::vector<Eigen::Vector3f> rays(static_cast<size_t>(cam.width) * cam.height);
    cv::Mat vignette(cam.height, cam.width, CV_32F);
    const double corner = std::hypot(std::max(cam.cx, cam.width - 1 - cam.cx),
                                     std::max(cam.cy, cam.height - 1 - cam.cy));
    ParallelFor(0, cam.height, [&](int64_t y) {
      for (int x = 0; x < cam.width; ++x) {
        Vec3 b;
        if (!cam.Unproject(Vec2(x, static_cast<double>(y)), &b)) b = Vec3(0, 0, 0);
        rays[y * cam.width + x] = b.cast<float>();
        const double r = std::hypot(x - cam.cx, y - cam.cy) / corner;
        vignette.at<float>(static_cast<int>(y), x) =
            static_cast<float>(1.0 - options_.vignetting * r * r);
      }
    });
    bearings_.push_back(std::move(rays));
    vignette_.push_back(vignette);
  }
}

const char* DotDiscName(DotDisc disc) {
  switch (disc) {
    case DotDisc::kFull:
      return "full";
    case DotDisc::kPartial:
      return "partial";
    case DotDisc::kHidden:
      break;
  }
  return "hidden";
}

SurfacePoint FootageRenderer::LocateFacePlane(const Vec2& st) const {
  SurfacePoint out;
  out.face = -1;
  const int gx = static_cast<int>(std::floor((st.x() - tri_origin_.x()) / tri_cell_));
  const int gy = static_cast<int>(std::floor((st.y() - tri_origin_.y()) / tri_cell_));
  if (gx < 0 || gy < 0 || gx >= tri_w_ || gy >= tri_h_) return out;
  for (int f : tri_grid_[gy * tri_w_ + gx]) {
    const Vec2 a = st_.row(F_(f, 0)).transpose();
    const Vec2 e1 = st_.row(F_(f, 1)).transpose() - a;
    const Vec2 e2 = st_.row(F_(f, 2)).transpose() - a;
    const double det = e1.x() * e2.y() - e1.y() * e2.x();
    if (std::abs(det) < 1e-15) continue;
    const Vec2 q = st - a;
    const double u = (q.x() * e2.y() - q.y() * e2.x()) / det;
    const double v = (e1.x() * q.y() - e1.y() * q.x()) / det;
    constexpr double kEps = 1e-9;
    if (u >= -kEps && v >= -kEps && u + v <= 1 + kEps) {
      out.face = f;
      out.bary = Vec3(1 - u - v, u, v);
      return out;
    }
  }
  return out;
}

double FootageRenderer::Albedo(const Vec2& st) const {
  const double fx = (st.x() - texture_origin_.x()) / texel_;
  const double fy = (st.y() - texture_origin_.y()) / texel_;
  const int x0 = std::clamp(static_cast<int>(std::floor(fx)), 0, albedo_texture_.cols - 2);
  const int y0 = std::clamp(static_cast<int>(std::floor(fy)), 0, albedo_texture_.rows - 2);
  const double ax = std::clamp(fx - x0, 0.0, 1.0);
  const double ay = std::clamp(fy - y0, 0.0, 1.0);
  const float* r0 = albedo_texture_.ptr<float>(y0);
  const float* r1 = albedo_texture_.ptr<float>(y0 + 1);
  const double v = (1 - ay) * ((1 - ax) * r0[x0] + ax * r0[x0 + 1]) +
                   ay * ((1 - ax) * r1[x0] + ax * r1[x0 + 1]);
  return options_.skin_albedo * (1 + options_.albedo_variation * v);
}

FootageRenderer::FaceInCamera FootageRenderer::PlaceFace(int camera,
                                                         const SceneState& state) const {
  const HelmetCamera& hc = rig_.cameras[camera];
  const Rigid3 cam_from_head = hc.cam_from_helmet * state.head_from_helmet.inverse();
  const MatX3d& X_head = *state.X_head;
  const int num_vertices = static_cast<int>(X_head.rows());
  HMC_CHECK(num_vertices == st_.rows());
  FaceInCamera face;
  face.X.resize(num_vertices, 3);
  MatX3d& X = face.X;
  const Mat3 R = cam_from_head.linear();
  const Vec3 t = cam_from_head.translation();
  ParallelFor(
      0, num_vertices,
      [&](int64_t v) { X.row(v) = (R * X_head.row(v).transpose() + t).transpose(); }, 2048);
  // Smooth normals: area-weighted face normals summed per vertex.
  const int num_faces = static_cast<int>(F_.rows());
  MatX3d face_n(num_faces, 3);
  ParallelFor(
      0, num_faces,
      [&](int64_t f) {
        const Vec3 p0 = X.row(F_(f, 0)), p1 = X.row(F_(f, 1)), p2 = X.row(F_(f, 2));
        face_n.row(f) = (p1 - p0).cross(p2 - p0).transpose();
      },
      2048);
  face.normal.resize(num_vertices, 3);
  ParallelFor(
      0, num_vertices,
      [&](int64_t v) {
        Vec3 n = Vec3::Zero();
        for (int f : vertex_faces_[v]) n += face_n.row(f).transpose();
        const double len = n.norm();
        face.normal.row(v) = (len > 0 ? Vec3(n / len) : Vec3(0, 0, -1)).transpose();
      },
      2048);
  return face;
}

std::vector<Vec3> FootageRenderer::HeadLights(int camera) const {
  const HelmetCamera& hc = rig_.cameras[camera];
  std::vector<Vec3> lights;
  for (const HelmetCamera& other : rig_.cameras) {
    const Vec3 centre_in_helmet = other.cam_from_helmet.inverse().translation();
    const Vec3 side = other.cam_from_helmet.linear().transpose() * Vec3::UnitX();
    lights.push_back(hc.cam_from_helmet * (centre_in_helmet + options_.light_offset * side));
  }
  return lights;
}

double FootageRenderer::Irradiance(const std::vector<Vec3>& lights, const Vec3& p,
                                   const Vec3& n) const {
  double irradiance = options_.ambient;
  for (const Vec3& light : lights) {
    const Vec3 to_light = light - p;
    const double dist2 = to_light.squaredNorm();
    const double cosine = n.dot(to_light) / std::sqrt(dist2);
    if (cosine > 0) {
      irradiance += options_.light_power * cosine * kLightReferenceMm * kLightReferenceMm / dist2;
    }
  }
  return irradiance;
}

double FootageRenderer::Specular(const std::vector<Vec3>& lights, const Vec3& p,
                                 const Vec3& n) const {
  if (options_.specular <= 0) return 0;
  const Vec3 to_eye = -p.normalized();
  double radiance = 0;
  for (const Vec3& light : lights) {
    const Vec3 to_light = light - p;
    const double dist2 = to_light.squaredNorm();
    const Vec3 l = to_light / std::sqrt(dist2);
    if (n.dot(l) <= 0 || n.dot(to_eye) <= 0) continue;
    const double n_h = n.dot((l + to_eye).normalized());
    if (n_h <= 0) continue;
    radiance += options_.light_power * kLightReferenceMm * kLightReferenceMm / dist2 *
                std::pow(n_h, options_.shininess);
  }
  return options_.specular * radiance;
}

std::vector<FootageRenderer::TagView> FootageRenderer::TagsInView(int camera) const {
  const HelmetCamera& hc = rig_.cameras[camera];
  const FisheyeCamera& cam = hc.camera;
  const int width = cam.width, height = cam.height;
  const FastFisheye fast(cam);
  std::vector<TagView> tag_views;
  for (size_t k = 0; k < rig_.tags.size(); ++k) {
    const HelmetTag& tag = rig_.tags[k];
    const Rigid3 cam_from_tag = hc.cam_from_helmet * tag.helmet_from_tag;
    TagView tv{cam_from_tag.linear(), cam_from_tag.translation(), tag.size,
               static_cast<int>(k), width, height, -1, -1};
    const double half = patterns_[k].PlateHalfExtent() * tag.size;
    bool all = true;
    for (int e = 0; e < 4 && all; ++e) {
      for (int k = 0; k <= 16; ++k) {
        const double a = -half + 2 * half * k / 16.0;
        const Vec3 local = e == 0   ? Vec3(a, -half, 0)
                           : e == 1 ? Vec3(half, a, 0)
                           : e == 2 ? Vec3(-a, half, 0)
                                    : Vec3(-half, -a, 0);
        Vec2 s;
        if (!fast.Project(cam_from_tag * local, &s)) {
          all = false;
          break;
        }
        tv.x0 = std::min(tv.x0, static_cast<int>(std::floor(s.x())) - 2);
        tv.y0 = std::min(tv.y0, static_cast<int>(std::floor(s.y())) - 2);
        tv.x1 = std::max(tv.x1, static_cast<int>(std::ceil(s.x())) + 2);
        tv.y1 = std::max(tv.y1, static_cast<int>(std::ceil(s.y())) + 2);
      }
    }
    if (!all) continue;
    tv.x0 = std::max(tv.x0, 0);
    tv.y0 = std::max(tv.y0, 0);
    tv.x1 = std::min(tv.x1, width - 1);
    tv.y1 = std::min(tv.y1, height - 1);
    tag_views.push_back(tv);
  }
  return tag_views;
}

double FootageRenderer::DotTransmission(int camera, int x, int y, int f, const Vec3& p0,
                                        const Vec3& p1, const Vec3& p2,
                                        const Vec2& st) const {
  const int gx = static_cast<int>((st.x() - grid_origin_.x()) / cell_);
  const int gy = static_cast<int>((st.y() - grid_origin_.y()) / cell_);
  if (gx < 0 || gy < 0 || gx >= grid_w_ || gy >= grid_h_) return 1.0;
  const FisheyeCamera& cam = rig_.cameras[camera].camera;
  const int width = cam.width, height = cam.height;
  const std::vector<Eigen::Vector3f>& rays = bearings_[camera];
  const double dot_r = options_.dot_radius;
  double keep = 1.0;
  bool have_jacobian = false;
  // Derivatives of st per pixel step in x and y.
  Vec2 jx = Vec2::Zero(), jy = Vec2::Zero();
  auto coords = [&](const Vec3& bb) -> Vec2 {
    return bb[0] * st_.row(F_(f, 0)).transpose() + bb[1] * st_.row(F_(f, 1)).transpose() +
           bb[2] * st_.row(F_(f, 2)).transpose();
  };
  const Vec2 here = st;
  for (int m : dot_grid_[gy * grid_w_ + gx]) {
    // Distance on the skin (the metric of the neutral at the marker), so
    // the dot is round on the skin.
    const Vec2 offset = here - dot_st_[m];
    const Vec2 g_offset = dot_metric_[m] * offset;
    const double len = std::sqrt(std::max(0.0, offset.dot(g_offset)));
    const double signed_mm = len - dot_r;
    if (signed_mm > 2.5) continue;
    if (!have_jacobian) {
      // The coordinates at the neighbouring pixels' rays on the same plane.
      auto at = [&](int nx, int ny, Vec2* out) {
        const Vec3 dn = rays[ny * width + nx].cast<double>();
        double sn;
        Vec3 bn;
        if (!IntersectPlane(dn, p0, p1, p2, &sn, &bn)) return false;
        *out = coords(bn);
        return true;
      };
      const int nx = x + 1 < width ? x + 1 : x - 1;
      const int ny = y + 1 < height ? y + 1 : y - 1;
      Vec2 sx, sy;
      if (!at(nx, y, &sx) || !at(x, ny, &sy)) break;
      jx = (sx - here) * (nx > x ? 1.0 : -1.0);
      jy = (sy - here) * (ny > y ? 1.0 : -1.0);
      have_jacobian = true;
    }
    // Signed distance to the dot's edge in pixels: the mm distance over its
    // rate of change per pixel (its gradient in st, G offset / len, through
    // the st Jacobian).
    double coverage;
    if (len < 1e-12) {
      coverage = 1.0;
    } else {
      const Vec2 grad = g_offset / len;
      const double rate = std::hypot(jx.dot(grad), jy.dot(grad));
      const double signed_px = rate > 0 ? signed_mm / rate : signed_mm * 1e9;
      coverage = std::clamp(0.5 - signed_px, 0.0, 1.0);
    }
    keep *= 1.0 - coverage;
  }
  return keep;
}

void FootageRenderer::CompositeTags(int camera, const std::vector<TagView>& tag_views,
                                    const std::vector<Vec3>& lights, int x, int y,
                                    double* value, double* dist, int* seen) const {
  const FisheyeCamera& cam = rig_.cameras[camera].camera;
  const int width = cam.width, height = cam.height;
  const std::vector<Eigen::Vector3f>& rays = bearings_[camera];
  const Vec3 d = rays[y * width + x].cast<double>();
  for (size_t k = 0; k < tag_views.size(); ++k) {
    const TagView& tv = tag_views[k];
    if (x < tv.x0 || x > tv.x1 || y < tv.y0 || y > tv.y1) continue;
    const Vec3 n = tv.R.col(2);
    const double n_t = n.dot(tv.t);
    const TagPattern& pattern = patterns_[tv.index];
    const double half = pattern.PlateHalfExtent();
    auto hit = [&](const Vec3& ray, double* s, Vec2* local) {
      const double denom = n.dot(ray);
      if (!(denom > 1e-12)) return false;
      *s = n_t / denom;
      const Vec3 q = tv.R.transpose() * (*s * ray - tv.t);
      *local = q.head<2>() / tv.size;
      return *s > 0;
    };
    double s_centre;
    Vec2 local_centre;
    if (!hit(d, &s_centre, &local_centre) || s_centre >= *dist) continue;
    if (std::abs(local_centre.x()) > half + 0.1 || std::abs(local_centre.y()) > half + 0.1) {
      continue;
    }
    // 4 x 4 supersamples, rays interpolated between neighbouring pixels.
    const int nx = x + 1 < width ? x + 1 : x - 1;
    const int ny = y + 1 < height ? y + 1 : y - 1;
    const Vec3 dx = (rays[y * width + nx].cast<double>() - d) * (nx > x ? 1.0 : -1.0);
    const Vec3 dy = (rays[ny * width + x].cast<double>() - d) * (ny > y ? 1.0 : -1.0);
    double sum = 0;
    int on_plate = 0;
    // Inside one pattern cell: the 16 samples' rays span a parallelogram,
    // whose central projection onto the plate is the convex quadrilateral
    // of the 4 corner samples; if these lie in one (convex) cell, so do all
    // 16, and the loop below would sum 16 equal values.
    int cell = -2;
    for (int j = 0; j < 4 && cell != -1; j += 3) {
      for (int i = 0; i < 4 && cell != -1; i += 3) {
        double s;
        Vec2 local;
        const Vec3 ray = d + (i - 1.5) / 4 * dx + (j - 1.5) / 4 * dy;
        const int c = hit(ray, &s, &local) ? pattern.Cell(local.x(), local.y()) : -1;
        cell = cell == -2 || cell == c ? c : -1;
        if (i == 0 && j == 0 && c >= 0) sum = 16 * pattern.Sample(local.x(), local.y());
      }
    }
    if (cell >= 0) {
      on_plate = 16;
    } else {
      sum = 0;
    }
    for (int j = 0; j < 4 && cell < 0; ++j) {
      for (int i = 0; i < 4; ++i) {
        const Vec3 ray = d + (i - 1.5) / 4 * dx + (j - 1.5) / 4 * dy;
        double s;
        Vec2 local;
        if (!hit(ray, &s, &local)) continue;
        const double white = pattern.Sample(local.x(), local.y());
        if (white < 0) continue;
        ++on_plate;
        sum += white;
      }
    }
    if (on_plate == 0) continue;
    const double reflectance =
        options_.tag_black + (options_.tag_white - options_.tag_black) * sum / on_plate;
    const double tag_value = reflectance * Irradiance(lights, s_centre * d, -n);
    const double coverage = on_plate / 16.0;
    *value = coverage * tag_value + (1 - coverage) * *value;
    if (std::abs(local_centre.x()) <= half && std::abs(local_centre.y()) <= half) {
      *dist = s_centre;
      *seen = kTagSurface - tv.index;
    }
  }
}

void FootageRenderer::ShadeInto(int camera, const SceneState& state, bool paint_dots,
                                cv::Mat* radiance, cv::Mat* depth, cv::Mat* surface,
                                SubdivisionStats* stats) const {
  const FisheyeCamera& cam = rig_.cameras[camera].camera;
  const int width = cam.width, height = cam.height;
  const FaceInCamera face = PlaceFace(camera, state);
  const MatX3d& X = face.X;
  const FisheyeTriangles tris = SubdivideForFisheye(cam, X, F_, options_.max_edge_error_px);
  if (stats) *stats = tris.stats;
  RasterOptions raster_options;
  raster_options.width = width;
  raster_options.height = height;
  // Only the triangle id per pixel: the shading below intersects each
  // pixel's exact ray with that triangle, so the raster's own depth and
  // barycentrics would be computed for nothing.
  std::vector<int32_t> seen_triangle;
  RasterizeTriangleIds(tris.screen, Eigen::VectorXd(), tris.F, raster_options, &seen_triangle);
  const std::vector<Vec3> lights = HeadLights(camera);
  const std::vector<TagView> tag_views = TagsInView(camera);
  const std::vector<Eigen::Vector3f>& rays = bearings_[camera];
  ParallelFor(0, height, [&](int64_t y64) {
    const int y = static_cast<int>(y64);
    float* out_row = radiance->ptr<float>(y);
    float* depth_row = depth ? depth->ptr<float>(y) : nullptr;
    int32_t* surface_row = surface ? surface->ptr<int32_t>(y) : nullptr;
    for (int x = 0; x < width; ++x) {
      const int index = y * width + x;
      const Vec3 d = rays[index].cast<double>();
      double value = options_.background;
      double dist = std::numeric_limits<double>::infinity();
      int seen = -1;
      // Face: the pixel's exact ray against the visible triangle's plane.
      const int sub = seen_triangle[index];
      if (sub >= 0 && d.squaredNorm() > 0) {
        const int f = tris.face[sub];
        const Vec3 p0 = X.row(F_(f, 0)), p1 = X.row(F_(f, 1)), p2 = X.row(F_(f, 2));
        double s;
        Vec3 b;
        if (IntersectPlane(d, p0, p1, p2, &s, &b) && s > 0) {
          dist = s;
          seen = f;
          const Vec3 p = s * d;
          Vec3 n = b[0] * face.normal.row(F_(f, 0)).transpose() +
                   b[1] * face.normal.row(F_(f, 1)).transpose() +
                   b[2] * face.normal.row(F_(f, 2)).transpose();
          n.normalize();
          const Vec2 st = b[0] * st_.row(F_(f, 0)).transpose() +
                          b[1] * st_.row(F_(f, 1)).transpose() +
                          b[2] * st_.row(F_(f, 2)).transpose();
          double albedo = Albedo(st);
          double keep = 1;  // the skin's share of the pixel (the rest is paint)
          if (paint_dots) {
            keep = DotTransmission(camera, x, y, f, p0, p1, p2, st);
            albedo = options_.dot_albedo + (albedo - options_.dot_albedo) * keep;
          }
          value = albedo * Irradiance(lights, p, n) + keep * Specular(lights, p, n);
        }
      }
      // Tags: a plate nearer than the face replaces it, blended at its edge.
      CompositeTags(camera, tag_views, lights, x, y, &value, &dist, &seen);
      out_row[x] = static_cast<float>(value);
      if (depth_row) depth_row[x] = static_cast<float>(dist);
      if (surface_row) surface_row[x] = seen;
    }
  });
}

ViewRender FootageRenderer::Render(int camera, const std::vector<SceneState>& samples,
                                   uint64_t noise_key, bool paint_dots,
                                   double shot_fraction) const {
  HMC_CHECK(camera >= 0 && camera < NumCameras() && !samples.empty());
  const FisheyeCamera& cam = rig_.cameras[camera].camera;
  ViewRender out;
  out.radiance = cv::Mat(cam.height, cam.width, CV_32F);  // every pixel is written
  out.depth = cv::Mat(cam.height, cam.width, CV_32F);
  out.surface = cv::Mat(cam.height, cam.width, CV_32S);
  const size_t middle = samples.size() / 2;
  cv::Mat one;
  if (samples.size() > 1) {
    out.radiance.setTo(0);
    one.create(cam.height, cam.width, CV_32F);
  }
  for (size_t i = 0; i < samples.size(); ++i) {
    const bool main = i == middle;
    ShadeInto(camera, samples[i], paint_dots, samples.size() == 1 ? &out.radiance : &one,
              main ? &out.depth : nullptr, main ? &out.surface : nullptr,
              main ? &out.stats : nullptr);
    if (samples.size() > 1) out.radiance += one / static_cast<double>(samples.size());
  }
  cv::Mat signal = out.radiance;  // a copy only when defocus or exposure changes it
  if (options_.defocus_px > 0) {
    cv::GaussianBlur(out.radiance, signal, cv::Size(0, 0), options_.defocus_px);
  }
  const double exposure = options_.ExposureAt(shot_fraction);
  if (exposure != 1) {
    cv::Mat exposed;  // a new buffer: signal may share out.radiance's
    signal.convertTo(exposed, CV_32F, exposure);
    signal = exposed;
  }
  out.image = RecordSensorImage(signal, options_.vignetting > 0 ? vignette_[camera] : cv::Mat(),
                                options_.read_noise, options_.shot_noise, noise_key,
                                options_.transfer == "srgb");
  return out;
}

std::vector<DotTruth> FootageRenderer::ProjectDots(int camera, const SceneState& state,
                                                   const ViewRender& view) const {
  const HelmetCamera& hc = rig_.cameras[camera];
  const FisheyeCamera& cam = hc.camera;
  const Rigid3 cam_from_head = hc.cam_from_helmet * state.head_from_helmet.inverse();
  const MatX3d& X_head = *state.X_head;
  auto corner = [&](int f, int i) -> Vec3 { return cam_from_head * Vec3(X_head.row(F_(f, i))); };
  // Whether mesh point q (camera frame) on triangle `face` is what the
  // camera sees at q's own pixel: the triangle seen there (or the rendered
  // depth) is not nearer on q's ray than kOcclusionToleranceMm.
  auto unoccluded = [&](int face, const Vec3& q, Vec2* pixel) {
    if (!cam.Project(q, pixel) || !cam.IsInImage(*pixel)) return false;
    const int px = std::clamp(static_cast<int>(std::lround(pixel->x())), 0, cam.width - 1);
    const int py = std::clamp(static_cast<int>(std::lround(pixel->y())), 0, cam.height - 1);
    const int seen = view.surface.at<int32_t>(py, px);
    const double range = q.norm();
    const Vec3 ray = q / range;
    double occluder = std::numeric_limits<double>::infinity();
    bool adjacent = false;  // the seen triangle shares a corner with q's
    for (int i = 0; seen >= 0 && i < 3; ++i) {
      for (int j = 0; j < 3; ++j) adjacent |= F_(seen, i) == F_(face, j);
    }
    if (adjacent) {
      // q's own surface patch: a neighbouring triangle cannot hide it (its
      // extended plane may pass in front on a crease, so do not test).
      occluder = range;
    } else if (seen >= 0) {
      // The triangle seen at the pixel, intersected with q's own ray.
      double s;
      Vec3 b;
      if (IntersectPlane(ray, corner(seen, 0), corner(seen, 1), corner(seen, 2), &s, &b) &&
          b.minCoeff() > -0.25) {
        occluder = s;
      } else {
        occluder = view.depth.at<float>(py, px) + 2.0;  // the pixel's depth, loosely
      }
    } else if (seen <= kTagSurface) {
      occluder = view.depth.at<float>(py, px);
    } else {
      occluder = 0;  // nothing at the pixel centre: q is on the silhouette
    }
    return occluder >= range - kOcclusionToleranceMm;
  };
  // Seen at most kMaxDiscViewDeg off the normal of triangle `face`.
  const double min_cos = std::cos(kMaxDiscViewDeg * M_PI / 180);
  // The cosine of the angle between triangle `face`'s normal and the view
  // ray to q (negative: back-facing).
  auto view_cos = [&](int face, const Vec3& q) {
    const Vec3 n = (corner(face, 1) - corner(face, 0)).cross(corner(face, 2) - corner(face, 0));
    return n.dot(-q) / (n.norm() * q.norm());
  };
  auto not_grazing = [&](int face, const Vec3& q) { return view_cos(face, q) >= min_cos; };
  // The disc samples in the unit disc of the skin: the rim and rings at
  // 3/4, 1/2 and 1/4 of the radius (16 + 12 + 8 + 4 points, ~0.3 mm apart
  // for the default dot), so a fold crossing the dot is found too.
  std::vector<Vec2> unit_samples;
  for (int ring = 4; ring >= 1; --ring) {
    const int count = 4 * ring;
    for (int k = 0; k < count; ++k) {
      const double phi = 2 * M_PI * (k + 0.5 * (ring % 2)) / count;
      unit_samples.push_back(ring / 4.0 * Vec2(std::cos(phi), std::sin(phi)));
    }
  }
  std::vector<DotTruth> out(markers_.size());
  ParallelFor(0, static_cast<int64_t>(markers_.size()), [&](int64_t m) {
    const SurfacePoint& sp = markers_[m].point;
    DotTruth& dot = out[m];
    if (sp.face < 0 || sp.face >= F_.rows()) return;
    dot.in_cam = cam_from_head * EvaluateSurfacePoint(sp, F_, X_head);
    dot.projects = cam.Project(dot.in_cam, &dot.pixel) && cam.IsInImage(dot.pixel);
    const Vec3 n = (corner(sp.face, 1) - corner(sp.face, 0))
                       .cross(corner(sp.face, 2) - corner(sp.face, 0));
    dot.facing = n.dot(-dot.in_cam) > 0;
    if (!dot.projects || !dot.facing) return;
    Vec2 pixel;
    dot.visible = unoccluded(sp.face, dot.in_cam, &pixel);
    // The whole disc: samples st = centre + L^-T (r u) with G = L L^T, so
    // that |offset| on the skin is r |u|. Every sample is tested, so that
    // `seen` says how much of a partial dot there is to find.
    const Eigen::Matrix2d L = dot_metric_[m].llt().matrixL();
    // The centre, then the disc: each sample's foreshortening where it is
    // unoccluded, and whether it is seen squarely.
    dot.view_cos = view_cos(sp.face, dot.in_cam);
    double seen = dot.visible ? std::max(0.0, dot.view_cos) : 0.0;
    int square = dot.visible && not_grazing(sp.face, dot.in_cam);
    int in_view = dot.visible;  // samples on the painted mesh, facing and unoccluded
    for (size_t k = 0; k < unit_samples.size(); ++k) {
      const Vec2 offset =
          L.transpose().triangularView<Eigen::Upper>().solve(options_.dot_radius * unit_samples[k]);
      const SurfacePoint sample = LocateFacePlane(dot_st_[m] + offset);
      if (sample.face < 0) continue;  // off the painted mesh
      const Vec3 q = cam_from_head * EvaluateSurfacePoint(sample, F_, X_head);
      if (!unoccluded(sample.face, q, &pixel)) continue;
      const double cos_q = view_cos(sample.face, q);
      seen += std::max(0.0, cos_q);
      square += not_grazing(sample.face, q);
      in_view += cos_q > 0;
    }
    const int samples = static_cast<int>(unit_samples.size()) + 1;
    dot.seen = seen / samples;
    if (!dot.visible) return;
    dot.disc = square == samples ? DotDisc::kFull : DotDisc::kPartial;
    dot.whole = in_view == samples;
    if (!dot.whole) return;
    // The image of the whole dot is the inside of its projected rim: its
    // centroid is the rim polygon's area centroid.
    double area = 0;
    Vec2 sum = Vec2::Zero(), first(0, 0), previous(0, 0);
    bool ok = true;
    for (int k = 0; k <= kRimSamples && ok; ++k) {
      Vec2 q(0, 0);
      if (k < kRimSamples) {
        const double phi = 2 * M_PI * k / kRimSamples;
        const Vec2 offset = L.transpose().triangularView<Eigen::Upper>().solve(
            options_.dot_radius * Vec2(std::cos(phi), std::sin(phi)));
        const SurfacePoint sample = LocateFacePlane(dot_st_[m] + offset);
        ok = sample.face >= 0 &&
             cam.Project(cam_from_head * EvaluateSurfacePoint(sample, F_, X_head), &q);
        if (k == 0) first = q;
      } else {
        q = first;
      }
      if (k > 0) {
        const double cross = previous.x() * q.y() - q.x() * previous.y();
        area += cross;
        sum += cross * (previous + q);
      }
      previous = q;
    }
    if (ok && std::abs(area) > 0) dot.whole_centroid = sum / (3 * area);
    if (dot.disc == DotDisc::kFull) dot.centroid = dot.whole_centroid;
  });
  return out;
}

std::vector<std::array<Vec2, 4>> FootageRenderer::ProjectTagCorners(int camera) const {
  const HelmetCamera& hc = rig_.cameras[camera];
  std::vector<std::array<Vec2, 4>> out;
  for (const HelmetTag& tag : rig_.tags) {
    std::array<Vec2, 4> corners;
    const std::vector<Vec3> c = tag.CornersInHelmet();
    for (int i = 0; i < 4; ++i) {
      if (!hc.camera.Project(hc.cam_from_helmet * c[i], &corners[i])) {
        corners[i].setConstant(std::numeric_limits<double>::quiet_NaN());
      }
    }
    out.push_back(corners);
  }
  return out;
}

}  // namespace hmc
