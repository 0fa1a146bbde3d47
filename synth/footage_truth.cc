// The ground truth of a rendered view (synth/footage.h): where each painted
// dot and each tag corner falls in the camera, and how much of each dot the
// camera sees.
#include "synth/footage.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Cholesky>

#include "core/error.h"
#include "core/parallel.h"
#include "core/triangle.h"

namespace hmc {

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
