#include "synth/footage.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <string>
#include <queue>
#include <vector>

#include <apriltag/apriltag.h>
#include <apriltag/common/image_u8.h>
#include <apriltag/tag36h11.h>
#include <fmt/format.h>
#include <gtest/gtest.h>

#include "core/parallel.h"
#include "synth/face_model.h"
#include "synth/footage_shot.h"
#include "synth/marker_layout.h"
#include "synth/performance.h"
#include "synth/synth_actor.h"

namespace hmc {
namespace {

// A small actor (fine enough that dots span several triangles) seen by a
// rig at a reduced image size, so each test renders in well under a second.
struct Scene {
  std::unique_ptr<FaceModel> model;
  std::vector<Marker> markers;
  HelmetRig rig;
  FootageRenderOptions options;
};

Scene MakeScene(int seed, int width = 640, int height = 512) {
  Scene scene;
  SynthActorOptions synth;
  synth.seed = seed;
  synth.grid_u = 192;
  synth.grid_v = 150;
  scene.model = std::make_unique<FaceModel>(synth);
  scene.markers = LayoutMarkers(scene.model->face(), static_cast<uint64_t>(seed), 0.8);
  HelmetRigOptions rig;
  rig.width = width;
  rig.height = height;
  rig.focal_px = HelmetRigOptions().focal_px * width / 1280;
  scene.rig = MakeShotRig(*scene.model, rig);
  scene.options.SetClean();
  return scene;
}

// The intensity centroid of each fully visible dot: weights 1 - I / I0
// (I with dots, I0 without; the ratio removes the shading), over the
// connected region of positive weight around the dot's projected pixel.
// A dot counts only if the ring around its region is its own surface
// (no occluding edge or image border touches it) and the region holds no
// other dot's projection.
struct Centroid {
  int marker;
  Vec2 measured;
  Vec2 truth;
  int pixels = 0;
};

std::vector<Centroid> DotCentroids(const ViewRender& with, const ViewRender& without,
                                   const std::vector<DotTruth>& dots) {
  const int w = with.radiance.cols, h = with.radiance.rows;
  // Each projecting dot's nearest pixel: a blob that reaches another dot's
  // is two dots whose anti-aliased edges touch, not one dot.
  std::map<int, int> dot_at_pixel;
  for (size_t m = 0; m < dots.size(); ++m) {
    if (!dots[m].projects) continue;
    dot_at_pixel[static_cast<int>(std::lround(dots[m].pixel.y())) * w +
                 static_cast<int>(std::lround(dots[m].pixel.x()))] = static_cast<int>(m);
  }
  std::vector<Centroid> out;
  for (size_t m = 0; m < dots.size(); ++m) {
    if (dots[m].disc != DotDisc::kFull) continue;
    const int cx = static_cast<int>(std::lround(dots[m].pixel.x()));
    const int cy = static_cast<int>(std::lround(dots[m].pixel.y()));
    auto weight = [&](int x, int y) {
      const float i0 = without.radiance.at<float>(y, x);
      return i0 > 0 ? 1.0 - with.radiance.at<float>(y, x) / i0 : 0.0;
    };
    if (cx < 2 || cy < 2 || cx >= w - 2 || cy >= h - 2 || weight(cx, cy) < 0.5) continue;
    std::vector<char> seen(static_cast<size_t>(w) * h, 0);
    std::queue<std::pair<int, int>> queue;
    queue.push({cx, cy});
    seen[cy * w + cx] = 1;
    double sw = 0, sx = 0, sy = 0;
    bool clean = true;
    int count = 0;
    while (!queue.empty() && clean) {
      const auto [x, y] = queue.front();
      queue.pop();
      const auto other = dot_at_pixel.find(y * w + x);
      if (other != dot_at_pixel.end() && other->second != static_cast<int>(m)) clean = false;
      const double wt = weight(x, y);
      sw += wt;
      sx += wt * x;
      sy += wt * y;
      ++count;
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
          const int nx = x + dx, ny = y + dy;
          if (nx < 1 || ny < 1 || nx >= w - 1 || ny >= h - 1) {
            clean = false;
            continue;
          }
          if (seen[ny * w + nx]) continue;
          seen[ny * w + nx] = 1;
          const int surface = with.surface.at<int32_t>(ny, nx);
          const double depth = with.depth.at<float>(ny, nx);
          if (surface < 0 || std::abs(depth - dots[m].in_cam.norm()) > 4.0) clean = false;
          if (weight(nx, ny) > 1e-9) queue.push({nx, ny});
        }
      }
      if (count > 4000) clean = false;
    }
    if (!clean || sw <= 0) continue;
    out.push_back({static_cast<int>(m), Vec2(sx / sw, sy / sw), dots[m].pixel, count});
  }
  return out;
}

// Where geometry alone puts a fully visible dot's centroid: the area
// centroid of the polygon of its projected rim (128 points of the disc's
// edge on the truth skin, projected exactly). The image of a fully visible
// dot is the inside of its projected rim, so this is its centroid up to
// the anti-aliasing, including the perspective and the curvature of the
// skin under the dot; it is not the projection of the marker when the skin
// is curved (the rim lies h = r^2 / (2 R) below the marker's tangent
// plane, and its centre projects h sin(view angle) off the marker).
Vec2 ProjectedRimCentroid(const FootageRenderer& renderer, const Scene& scene, const MatX3d& X,
                          const SceneState& state, int camera, int marker) {
  const Eigen::Matrix2d L = renderer.dot_metric(marker).llt().matrixL();
  const HelmetCamera& hc = scene.rig.cameras[camera];
  const Rigid3 cam_from_head = hc.cam_from_helmet * state.head_from_helmet.inverse();
  constexpr int kRim = 128;
  std::vector<Vec2> polygon;
  for (int k = 0; k < kRim; ++k) {
    const Vec2 u(std::cos(2 * M_PI * k / kRim), std::sin(2 * M_PI * k / kRim));
    const Vec2 offset =
        L.transpose().triangularView<Eigen::Upper>().solve(scene.options.dot_radius * u);
    const SurfacePoint sp = renderer.LocateFacePlane(renderer.dot_centres()[marker] + offset);
    EXPECT_GE(sp.face, 0);
    Vec2 pixel(0, 0);
    if (sp.face >= 0) {
      EXPECT_TRUE(hc.camera.Project(
          cam_from_head * EvaluateSurfacePoint(sp, scene.model->neutral().F, X), &pixel));
    }
    polygon.push_back(pixel);
  }
  double area = 0;
  Vec2 centroid = Vec2::Zero();
  for (int k = 0; k < kRim; ++k) {
    const Vec2& p = polygon[k];
    const Vec2& q = polygon[(k + 1) % kRim];
    const double cross = p.x() * q.y() - q.x() * p.y();
    area += cross;
    centroid += cross * (p + q);
  }
  return centroid / (3 * area);
}

TEST(FootageTest, DotCentroidsMatchProjectedMarkers) {
  std::vector<double> marker_errors, flat_errors, centroid_errors;
  std::map<std::string, std::vector<double>> by_region;
  std::vector<std::pair<double, std::string>> worst;
  int num_full = 0, num_partial = 0, num_hidden = 0, num_unmeasured = 0;
  double worst_truth_centroid = 0;
  for (int seed : {1, 2, 3}) {
    Scene scene = MakeScene(seed, 1280, 1024);
    const FootageRenderer renderer(scene.model->neutral(), scene.model->face().st,
                                   scene.markers, scene.rig, scene.options, seed);
    PerformanceOptions perf;
    perf.frames = 40;
    perf.seed = seed;
    const ShotPerformance performance = MakePerformance(*scene.model, perf);
    for (int f : {7 + seed, 31 - seed}) {
      const MatX3d X = scene.model->Evaluate(performance.activations[f]);
      const SceneState state{&X, performance.head_from_helmet[f]};
      for (int c = 0; c < renderer.NumCameras(); ++c) {
        const ViewRender with = renderer.Render(c, {state}, 0, true);
        const ViewRender without = renderer.Render(c, {state}, 0, false);
        const std::vector<DotTruth> dots = renderer.ProjectDots(c, state, with);
        const std::vector<Centroid> centroids = DotCentroids(with, without, dots);
        int full = 0;
        for (size_t m = 0; m < dots.size(); ++m) {
          const DotTruth& d = dots[m];
          if (!d.projects) continue;
          EXPECT_EQ(d.disc != DotDisc::kHidden, d.visible);
          EXPECT_EQ(d.disc == DotDisc::kFull, d.centroid.allFinite());
          full += d.disc == DotDisc::kFull;
          num_partial += d.disc == DotDisc::kPartial;
          num_hidden += d.disc == DotDisc::kHidden;
          if (d.disc == DotDisc::kFull) {
            // The ground truth's centroid against this test's own, finer
            // rim polygon.
            const Vec2 rim = ProjectedRimCentroid(renderer, scene, X, state, c, m);
            worst_truth_centroid = std::max(worst_truth_centroid, (rim - d.centroid).norm());
          }
        }
        num_full += full;
        EXPECT_GT(full, 30) << "seed " << seed << " cam " << c;
        // Fully visible dots are isolated blobs of their own surface, but
        // two dots' anti-aliased edges may touch in the image.
        num_unmeasured += full - static_cast<int>(centroids.size());
        for (const Centroid& cen : centroids) {
          const DotTruth& d = dots[cen.marker];
          const double error = (cen.measured - d.centroid).norm();
          const double marker_error = (cen.measured - d.pixel).norm();
          const double curvature_offset = (d.centroid - d.pixel).norm();
          const std::string& name = scene.markers[cen.marker].name;
          // Every fully visible dot images where the ground truth says.
          EXPECT_LT(error, 0.1) << name << " seed " << seed << " frame " << f << " cam " << c;
          centroid_errors.push_back(error);
          marker_errors.push_back(marker_error);
          by_region[name.substr(0, name.rfind('_'))].push_back(marker_error);
          worst.push_back({marker_error,
                           fmt::format("{} seed {} frame {} cam {}: truth centroid {:.3f} px off "
                                       "the marker, measured {:.3f} px off the truth centroid",
                                       name, seed, f, c, curvature_offset, error)});
          // Skin flat enough under the dot (the geometry puts its centroid
          // within 0.02 px of the marker): the marker itself is found.
          if (curvature_offset < 0.02) {
            flat_errors.push_back(marker_error);
            EXPECT_LT(marker_error, 0.1) << name << " seed " << seed << " frame " << f;
          }
        }
      }
    }
  }
  auto quantile = [](std::vector<double> v, double q) {
    std::sort(v.begin(), v.end());
    return v[static_cast<size_t>(q * (v.size() - 1))];
  };
  EXPECT_LT(worst_truth_centroid, 0.01);
  EXPECT_LE(num_unmeasured, num_full / 50) << "fully visible dots whose blobs touch others";
  ASSERT_GT(centroid_errors.size(), 600u);
  ASSERT_GT(flat_errors.size(), 50u);
  // The typical fully visible dot is also within 0.1 px of its marker's
  // projection, but not every one: on curved skin (lips, brows, nose) the
  // centroid is the truth centroid, not the marker (docs/footage.md).
  EXPECT_LT(quantile(marker_errors, 0.5), 0.1);
  RecordProperty("centroid_max_px", std::to_string(quantile(centroid_errors, 1.0)));
  RecordProperty("marker_median_px", std::to_string(quantile(marker_errors, 0.5)));
  std::printf("dots in the image: %d full, %d partial, %d hidden (%.1f%% of the centre-visible "
              "ones are partial); %d full ones not measurable (blobs touching)\n",
              num_full, num_partial, num_hidden,
              100.0 * num_partial / std::max(1, num_full + num_partial), num_unmeasured);
  std::printf("centroid - truth centroid over %zu full dots (px): median %.4f p90 %.4f p99 %.4f "
              "max %.4f (truth vs test rim polygon: %.4f)\n",
              centroid_errors.size(), quantile(centroid_errors, 0.5),
              quantile(centroid_errors, 0.9), quantile(centroid_errors, 0.99),
              quantile(centroid_errors, 1.0), worst_truth_centroid);
  std::printf("centroid - projected marker (px): median %.4f p90 %.4f p99 %.4f max %.4f\n",
              quantile(marker_errors, 0.5), quantile(marker_errors, 0.9),
              quantile(marker_errors, 0.99), quantile(marker_errors, 1.0));
  std::printf("  %zu dots on flat skin (truth centroid < 0.02 px off the marker): median %.4f "
              "max %.4f\n",
              flat_errors.size(), quantile(flat_errors, 0.5), quantile(flat_errors, 1.0));
  for (const auto& [region, errors] : by_region) {
    std::printf("  %-14s %3zu dots  centroid - marker median %.3f  max %.3f px\n",
                region.c_str(), errors.size(), quantile(errors, 0.5), quantile(errors, 1.0));
  }
  std::sort(worst.rbegin(), worst.rend());
  for (size_t i = 0; i < std::min<size_t>(3, worst.size()); ++i) {
    std::printf("  worst: %.3f px %s\n", worst[i].first, worst[i].second.c_str());
  }
}

TEST(FootageTest, HelmetTagsAreDetectedAtTheirProjectedCorners) {
  Scene scene = MakeScene(3, 1280, 1024);
  const FootageRenderer renderer(scene.model->neutral(), scene.model->face().st, scene.markers,
                                 scene.rig, scene.options, 3);
  const MatX3d X = scene.model->neutral().V;
  const SceneState state{&X, Rigid3::Identity()};
  apriltag_family_t* family = tag36h11_create();
  apriltag_detector_t* detector = apriltag_detector_create();
  apriltag_detector_add_family(detector, family);
  detector->quad_decimate = 1.0;
  detector->nthreads = 1;
  double worst_corner = 0;
  for (int c = 0; c < renderer.NumCameras(); ++c) {
    const ViewRender view = renderer.Render(c, {state}, 0);
    image_u8_t image{view.image.cols, view.image.rows, static_cast<int32_t>(view.image.step),
                     view.image.data};
    zarray_t* detections = apriltag_detector_detect(detector, &image);
    const auto truth = renderer.ProjectTagCorners(c);
    std::vector<int> found(truth.size(), 0);
    for (int i = 0; i < zarray_size(detections); ++i) {
      apriltag_detection_t* det;
      zarray_get(detections, i, &det);
      ASSERT_GE(det->id, 0);
      ASSERT_LT(det->id, static_cast<int>(truth.size())) << "a tag that is not on the helmet";
      found[det->id] = 1;
      for (int k = 0; k < 4; ++k) {
        // AprilTag puts pixel centres at +0.5 (pixel (0, 0) spans [0, 1]);
        // hmc follows OpenCV (centre at 0), core/types.h.
        const Vec2 corner(det->p[k][0] - 0.5, det->p[k][1] - 0.5);
        worst_corner = std::max(worst_corner, (corner - truth[det->id][k]).norm());
        EXPECT_LT((corner - truth[det->id][k]).norm(), 0.5)
            << "cam " << c << " tag " << det->id << " corner " << k << " diff " << (corner - truth[det->id][k]).transpose();
      }
    }
    apriltag_detections_destroy(detections);
    // Every tag projects into the image here, and none is hidden by the face.
    for (size_t t = 0; t < truth.size(); ++t) {
      for (const Vec2& p : truth[t]) EXPECT_TRUE(scene.rig.cameras[c].camera.IsInImage(p));
      EXPECT_TRUE(found[t]) << "cam " << c << " tag " << t << " not detected";
    }
  }
  std::printf("tag corner error (px): max %.4f\n", worst_corner);
  apriltag_detector_destroy(detector);
  tag36h11_destroy(family);
}

TEST(FootageTest, OccludedDotsAreInvisibleByDepth) {
  Scene scene = MakeScene(4);
  const FootageRenderer renderer(scene.model->neutral(), scene.model->face().st, scene.markers,
                                 scene.rig, scene.options, 4);
  const MatX3d X = scene.model->neutral().V;
  int occluded = 0, checked = 0, silhouette = 0;
  // The head turned far in the helmet: the nose hides the far cheek's dots.
  for (double yaw : {-40.0, 0.0, 40.0}) {
    Rigid3 head_from_helmet = Rigid3::Identity();
    head_from_helmet.linear() =
        Eigen::AngleAxisd(yaw * M_PI / 180, Vec3::UnitY()).toRotationMatrix();
    const SceneState state{&X, head_from_helmet};
    for (int c = 0; c < renderer.NumCameras(); ++c) {
      const ViewRender view = renderer.Render(c, {state}, 0);
      const std::vector<DotTruth> dots = renderer.ProjectDots(c, state, view);
      for (const DotTruth& d : dots) {
        if (!d.projects || !d.facing) continue;
        const int px = static_cast<int>(std::lround(d.pixel.x()));
        const int py = static_cast<int>(std::lround(d.pixel.y()));
        const double depth = view.depth.at<float>(py, px);
        const double range = d.in_cam.norm();
        ++checked;
        // Independent check: the rendered depth at the dot's pixel. A
        // visible dot is the nearest surface (within the pixel's spread of
        // depth on a slanted surface); an invisible one lies well behind.
        if (d.visible) {
          EXPECT_GT(depth, range - 3.0) << "visible dot behind an occluder";
        } else if (std::isinf(depth)) {
          // On a silhouette (a lip edge at the mouth opening): the pixel
          // centre sees past the surface, the dot counts as hidden.
          ++silhouette;
        } else {
          ++occluded;
          EXPECT_LT(depth, range - 0.2) << "invisible dot with nothing in front of it";
        }
      }
    }
  }
  EXPECT_GT(checked, 300);
  EXPECT_GT(occluded, 5) << "the turned head must hide some dots";
  EXPECT_LT(silhouette, checked / 20);
}

TEST(FootageTest, SubdivisionBoundsTheEdgeError) {
  Scene scene = MakeScene(5);
  const HelmetCamera& hc = scene.rig.cameras[0];
  // Close to the lens and off axis, where projected edges bend.
  MatX3d X_cam = scene.model->neutral().V;
  for (int v = 0; v < X_cam.rows(); ++v) {
    X_cam.row(v) = (hc.cam_from_helmet * Vec3(X_cam.row(v))).transpose();
  }
  X_cam.col(2).array() -= 120;  // the face ~5 cm from the lens
  const MatX3i& F = scene.model->neutral().F;
  const double tolerance = 0.05;
  const FisheyeTriangles tris = SubdivideForFisheye(hc.camera, X_cam, F, tolerance);
  EXPECT_GT(tris.stats.split_triangles, 0);
  EXPECT_GT(tris.stats.output_triangles, tris.stats.input_triangles);
  EXPECT_LE(tris.stats.max_edge_error_px, tolerance);
  // Independent measure on every 7th rasterized triangle: recover each
  // corner's 3D point (its ray on the mesh triangle's plane), sample the 3D
  // edge, project exactly and take the largest distance to the chord.
  double worst = 0;
  for (int t = 0; t < tris.F.rows(); t += 7) {
    const int f = tris.face[t];
    const Vec3 p0 = X_cam.row(F(f, 0)), p1 = X_cam.row(F(f, 1)), p2 = X_cam.row(F(f, 2));
    const Vec3 n = (p1 - p0).cross(p2 - p0);
    Vec3 corner[3];
    Vec2 pixel[3];
    for (int i = 0; i < 3; ++i) {
      pixel[i] = tris.screen.row(tris.F(t, i)).head<2>().transpose();
      Vec3 ray;
      ASSERT_TRUE(hc.camera.Unproject(pixel[i], &ray));
      corner[i] = ray * (n.dot(p0) / n.dot(ray));
    }
    for (int e = 0; e < 3; ++e) {
      const Vec3& a = corner[e];
      const Vec3& b = corner[(e + 1) % 3];
      const Vec2 chord = pixel[(e + 1) % 3] - pixel[e];
      if (chord.norm() < 1e-9) continue;
      const Vec2 normal = Vec2(-chord.y(), chord.x()).normalized();
      for (int k = 1; k < 16; ++k) {
        Vec2 q;
        ASSERT_TRUE(hc.camera.Project(Vec3(a + (b - a) * (k / 16.0)), &q));
        worst = std::max(worst, std::abs(normal.dot(q - pixel[e])));
      }
    }
  }
  RecordProperty("worst_edge_error_px", std::to_string(worst));
  // The midpoint sagitta is the largest deviation up to third-order terms.
  EXPECT_LT(worst, tolerance * 1.05);
}

TEST(FootageTest, DeterministicAndIndependentOfThreadCount) {
  Scene scene = MakeScene(6);
  FootageRenderOptions noisy;  // defaults: noise and vignetting on
  noisy.defocus_px = 0.7;
  const FootageRenderer renderer(scene.model->neutral(), scene.model->face().st, scene.markers,
                                 scene.rig, noisy, 6);
  const MatX3d X = scene.model->neutral().V;
  const SceneState state{&X, Rigid3::Identity()};
  cv::Mat first, second, third;
  std::vector<DotTruth> dots_one;
  {
    ThreadLimit limit(1);
    const ViewRender view = renderer.Render(1, {state}, 99);
    first = view.image;
    dots_one = renderer.ProjectDots(1, state, view);
  }
  const ViewRender view = renderer.Render(1, {state}, 99);
  second = view.image;
  const std::vector<DotTruth> dots_all = renderer.ProjectDots(1, state, view);
  ASSERT_EQ(dots_one.size(), dots_all.size());
  int full = 0;
  for (size_t m = 0; m < dots_one.size(); ++m) {
    EXPECT_EQ(dots_one[m].disc, dots_all[m].disc);
    EXPECT_EQ(dots_one[m].pixel, dots_all[m].pixel);
    EXPECT_EQ(dots_one[m].centroid.allFinite(), dots_all[m].centroid.allFinite());
    if (dots_one[m].centroid.allFinite()) {
      EXPECT_EQ(dots_one[m].centroid, dots_all[m].centroid);
    }
    full += dots_one[m].disc == DotDisc::kFull;
  }
  EXPECT_GT(full, 10);
  third = renderer.Render(1, {state}, 100).image;
  EXPECT_EQ(cv::norm(first, second, cv::NORM_INF), 0);
  EXPECT_GT(cv::norm(first, third, cv::NORM_INF), 0) << "the noise key must change the noise";
}

// Exposure scales the recorded levels (its drift reaches exposure * (1 +
// drift) at the shot's last frame) and leaves the radiance alone; the
// skin's specular highlights only add light.
TEST(FootageTest, ExposureDriftAndSpecularity) {
  Scene scene = MakeScene(7, 320, 256);
  const MatX3d X = scene.model->neutral().V;
  const SceneState state{&X, Rigid3::Identity()};
  auto render = [&](const FootageRenderOptions& options, double shot_fraction) {
    const FootageRenderer renderer(scene.model->neutral(), scene.model->face().st,
                                   scene.markers, scene.rig, options, 7);
    return renderer.Render(0, {state}, 1, true, shot_fraction);
  };
  const ViewRender lit = render(scene.options, 0);
  FootageRenderOptions half = scene.options;
  half.exposure = 0.5;
  const ViewRender dim = render(half, 0);
  EXPECT_EQ(cv::norm(lit.radiance, dim.radiance, cv::NORM_INF), 0);
  cv::Mat expected;
  lit.image.convertTo(expected, CV_32F, 0.5);
  cv::Mat got;
  dim.image.convertTo(got, CV_32F);
  EXPECT_LE(cv::norm(expected, got, cv::NORM_INF), 1.0) << "half the exposure, half the level";
  EXPECT_GT(cv::mean(lit.image)[0], 10);

  FootageRenderOptions drifting = scene.options;
  drifting.exposure_drift = -0.5;
  EXPECT_EQ(cv::norm(render(drifting, 1).image, dim.image, cv::NORM_INF), 0);
  EXPECT_EQ(cv::norm(render(drifting, 0).image, lit.image, cv::NORM_INF), 0);

  FootageRenderOptions glossy = scene.options;
  glossy.specular = 0.2;
  const ViewRender shiny = render(glossy, 0);
  cv::Mat added = shiny.radiance - lit.radiance;
  double lo = 0, hi = 0;
  cv::minMaxLoc(added, &lo, &hi);
  EXPECT_GE(lo, 0);
  EXPECT_GT(hi, 0.01) << "no highlight on the skin";
}

}  // namespace
}  // namespace hmc
