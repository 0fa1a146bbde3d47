// Steps 1 and 2 of the footage renderer (synth/footage.h): the face placed
// and rasterized in one camera, then each pixel shaded: skin, painted dots,
// head lights, tags.
#include "synth/footage.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <opencv2/core.hpp>

#include "core/error.h"
#include "core/parallel.h"
#include "core/raster.h"
#include "core/triangle.h"

namespace hmc {
namespace {

// Reference distance of the head lights' irradiance (mm).
constexpr double kLightReferenceMm = 170.0;

}  // namespace

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

}  // namespace hmc
