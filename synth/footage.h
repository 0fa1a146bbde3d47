// The software renderer of synthetic helmet-camera footage (`hmc synth
// shot`): what one fisheye camera of the helmet rig (synth/helmet_rig.h)
// records of the painted face and the helmet tags. docs/footage.md explains
// the method and what is exact.
//
// 1. Visibility: the face's triangles are projected through the
//    Kannala-Brandt model and subdivided in screen space
//    (synth/fisheye_subdivision.h), then rasterized with core/raster.h's
//    z-buffer (triangle ids only).
// 2. Shading, per pixel: the pixel's exact ray (precomputed bearings) is
//    intersected with the visible (flat) triangle of the mesh, so the
//    surface point, its UV and depth are exact, not interpolated through
//    the projection. The albedo is the face-plane (UV) texture: a smooth skin
//    variation plus the painted dots, discs round on the neutral skin and
//    attached to UV (they stretch with the skin), anti-aliased by their
//    signed distance in pixels. Lambert
//    shading by one light beside each camera (inverse-square falloff).
//    Tags: planar plates, ray-intersected exactly and supersampled.
// 3. Camera: optional motion blur (sub-frame samples), defocus (Gaussian),
//    vignetting, sensor noise (read + shot noise, seeded per pixel), 8-bit
//    (synth/sensor_noise.h).
// Parallel over rows via core/parallel.h; deterministic whatever the thread
// count.
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "core/actor.h"
#include "core/mesh.h"
#include "core/options.h"
#include "synth/fisheye_subdivision.h"
#include "synth/helmet_rig.h"
#include "synth/tag_render.h"

namespace hmc {

struct FootageRenderOptions {
  double dot_radius = 1.2;          // painted dot radius on the skin (mm)
  double dot_albedo = 0.07;         // reflectance of the dot paint
  double skin_albedo = 0.6;         // mean skin reflectance
  double albedo_variation = 0.1;    // relative amplitude of the skin's albedo variation
  double tag_white = 0.85;          // reflectance of the tags' white
  double tag_black = 0.04;          // reflectance of the tags' black
  double background = 0.015;        // radiance where nothing is hit (helmet interior)
  double ambient = 0.06;            // ambient light (fraction of full exposure)
  double light_power = 0.55;        // each head light's irradiance at 170 mm, head-on
  double light_offset = 22;         // head light offset beside each camera (mm)
  double exposure = 1.0;            // gain on the radiance before the sensor (1 = as lit)
  double exposure_drift = 0;        // relative change of the exposure from the first frame to the last (linear; -0.2 = 20% darker at the end)
  double specular = 0;              // skin's specular (Blinn-Phong) reflectance (0 = matte; the dots' paint stays matte)
  double shininess = 30;            // Blinn-Phong exponent of the skin's highlights
  double vignetting = 0.3;          // darkening at the image corner (0 = off)
  double read_noise = 1.0;          // std of the sensor read noise (8-bit levels; 0 = off)
  double shot_noise = 0.05;         // shot-noise variance per level of signal (0 = off)
  int motion_blur_samples = 1;      // sub-frame samples over the shutter (1 = off)
  double shutter = 0.5;             // exposure as a fraction of the frame interval
  double defocus_px = 0;            // Gaussian defocus blur sigma (px; 0 = off)
  double max_edge_error_px = 0.05;  // fisheye subdivision tolerance (px)
  std::string transfer = "linear";  // 8-bit encoding: linear | srgb (the sRGB curve, as most cameras write PNG)

  void Register(OptionFields* fields);
  bool Check() const;
  // No noise, vignetting, blur or defocus: the clean image of exact tests.
  void SetClean();
  // The exposure at `shot_fraction` of the shot (0 = first frame, 1 = last):
  // exposure * (1 + exposure_drift * shot_fraction).
  double ExposureAt(double shot_fraction) const;
};

// One instant of the scene.
struct SceneState {
  const MatX3d* X_head = nullptr;  // V x 3 face vertex positions (head space, mm)
  Rigid3 head_from_helmet = Rigid3::Identity();
};

struct ViewRender {
  cv::Mat radiance;  // CV_32F, linear, 1 = full scale, before noise and quantisation
  cv::Mat image;     // CV_8U: the recorded frame
  cv::Mat depth;     // CV_32F distance from the camera centre along each pixel's ray
                     // (mm), +inf where nothing is hit
  cv::Mat surface;   // CV_32S per pixel: mesh triangle seen, kTagSurface - tag
                     // index for a tag, -1 for nothing
  SubdivisionStats stats;
};
constexpr int kTagSurface = -1000;

// How much of a painted dot a camera sees (dots_2d.csv `disc`).
enum class DotDisc {
  kHidden,   // the marker's own point is not visible
  kPartial,  // the marker's point is visible, but part of the disc is hidden
             // or seen at a grazing angle (its centroid is not the marker's)
  kFull,     // the whole disc is visible and none of it grazing
};
const char* DotDiscName(DotDisc disc);  // "hidden", "partial", "full"

// Ground truth of one dot in one camera.
struct DotTruth {
  Vec2 pixel = Vec2::Zero();  // projection of the marker's surface point
  Vec3 in_cam = Vec3::Zero();
  bool projects = false;      // in front of the lens and inside the image
  bool facing = false;        // its triangle faces the camera
  bool visible = false;       // projects, faces and nothing is nearer on its ray
  DotDisc disc = DotDisc::kHidden;  // the whole painted disc (ProjectDots)
  // For a kFull dot, where its image's intensity centroid lies: the area
  // centroid of its projected rim (kRimSamples points of the disc's edge
  // on the truth mesh). On curved skin this is not `pixel`: the rim lies
  // h = r^2 / (2 R) below the marker's tangent plane (R the skin's radius
  // of curvature), so its centre projects about h sin(view angle) away.
  // NaN for other dots.
  Vec2 centroid = Vec2::Constant(std::numeric_limits<double>::quiet_NaN());
  // How much of the dot the camera sees, as a fraction of the dot seen
  // face-on: the mean over its centre and disc samples (1 +
  // FootageRenderer::kDiscSamples) of the cosine between the skin's normal
  // and the view ray where the sample is on the painted mesh and unoccluded
  // (0 where not). A face-on dot has 1, a kFull one at least
  // cos(kMaxDiscViewDeg) = 0.5; a kPartial dot foreshortened to a sliver
  // or cut by a silhouette little; a dot whose centre is hidden may still
  // show part of its disc.
  double seen = 0.0;
  // The cosine between the skin's normal at the marker's point and the
  // view ray (negative: back-facing); 0 where the point does not project.
  double view_cos = 0.0;
  // The whole disc is in view (its centre and every disc sample on the
  // painted mesh, facing the camera and unoccluded), however grazing: a
  // kFull dot, or a kPartial one that is only foreshortened.
  bool whole = false;
  // For a `whole` dot, the area centroid of its projected rim (as
  // `centroid`, which only kFull dots have); NaN for other dots.
  Vec2 whole_centroid = Vec2::Constant(std::numeric_limits<double>::quiet_NaN());
};

class FootageRenderer {
 public:
  // neutral: the actor's neutral mesh (triangles; positions shape the dots);
  // st: V x 2 face-plane texture coordinates (mm, linear in UV) in which
  // the dots are round; markers: the painted dots; seed: the albedo texture.
  FootageRenderer(const TriMesh& neutral, const MatX2d& st,
                  const std::vector<Marker>& markers, const HelmetRig& rig,
                  const FootageRenderOptions& options, uint64_t seed);

  const HelmetRig& rig() const { return rig_; }
  int NumCameras() const { return static_cast<int>(rig_.cameras.size()); }
  // Moves camera `camera` on the helmet (a knock, synth/footage_shot.h);
  // the frames rendered after the call see it there.
  void SetCamFromHelmet(int camera, const Rigid3& cam_from_helmet) {
    rig_.cameras[camera].cam_from_helmet = cam_from_helmet;
  }

  // Renders camera `camera` over `samples` (one: no motion blur; several:
  // averaged over the shutter; depth and surface are those of the middle
  // sample). noise_key seeds the sensor noise (distinct per frame and
  // camera). paint_dots = false leaves the dots out (tests compare).
  // shot_fraction: where the frame lies in the shot (0 = first, 1 = last),
  // for the exposure's drift (FootageRenderOptions::ExposureAt).
  ViewRender Render(int camera, const std::vector<SceneState>& samples,
                    uint64_t noise_key, bool paint_dots = true,
                    double shot_fraction = 0) const;

  // Each marker's projection and visibility in `camera` for `state`;
  // `view` (rendered from the same state) supplies the occluder at the
  // projected pixel: the dot is visible if the ray to it hits nothing
  // nearer than kOcclusionToleranceMm in front of it.
  std::vector<DotTruth> ProjectDots(int camera, const SceneState& state,
                                    const ViewRender& view) const;
  // `disc`: the centre and kDiscSamples points of the painted disc (its
  // rim and rings at 3/4, 1/2, 1/4 of its radius) are each tested like the
  // centre (projects, visible at its own pixel) and must be seen at most
  // kMaxDiscViewDeg off their triangle's normal; all pass: kFull. 60
  // degrees: beyond it the dot is foreshortened more than 2:1 and its far
  // half is crowded into a few pixels.
  static constexpr double kOcclusionToleranceMm = 0.3;
  static constexpr int kDiscSamples = 40;
  static constexpr double kMaxDiscViewDeg = 60;
  static constexpr int kRimSamples = 64;

  // Each tag's four corners (HelmetTag::CornersInHelmet order) in `camera`;
  // a corner that does not project is NaN.
  std::vector<std::array<Vec2, 4>> ProjectTagCorners(int camera) const;

  // The face-plane centre of each marker's dot (mm).
  const std::vector<Vec2>& dot_centres() const { return dot_st_; }

  // The painted disc of marker m in the face plane: points st with
  // (st - centre)^T G (st - centre) <= dot_radius^2, G = dot_metric(m), the
  // neutral surface's metric at the marker (3D mm^2 per st mm^2), so the dot
  // is round on the skin, not in UV.
  const Eigen::Matrix2d& dot_metric(int m) const { return dot_metric_[m]; }

  // The mesh point at face-plane coordinates st (face -1 if none).
  SurfacePoint LocateFacePlane(const Vec2& st) const;

 private:
  // The face in one camera's frame: vertex positions and smooth normals.
  struct FaceInCamera {
    MatX3d X;
    MatX3d normal;
  };
  // A tag plate in one camera's frame, with its image bounding box.
  struct TagView {
    Mat3 R;  // cam_from_tag rotation
    Vec3 t;
    double size;
    int index;  // into rig_.tags
    int x0, y0, x1, y1;
  };
  // Shading (step 2 of the header): radiance, and optionally depth and the
  // surface seen, of every pixel of `camera` for one scene state.
  void ShadeInto(int camera, const SceneState& state, bool paint_dots,
                 cv::Mat* radiance, cv::Mat* depth, cv::Mat* surface,
                 SubdivisionStats* stats) const;
  FaceInCamera PlaceFace(int camera, const SceneState& state) const;
  // One light beside each camera of the rig, in `camera`'s frame.
  std::vector<Vec3> HeadLights(int camera) const;
  // Lambert irradiance at p with normal n: ambient plus each light with
  // inverse-square falloff (light_power at 170 mm head-on).
  double Irradiance(const std::vector<Vec3>& lights, const Vec3& p, const Vec3& n) const;
  // The skin's specular radiance at p with normal n seen from the camera
  // centre (Blinn-Phong: each light's irradiance times specular *
  // (n.h)^shininess, h the half vector of light and view); 0 when matte.
  double Specular(const std::vector<Vec3>& lights, const Vec3& p, const Vec3& n) const;
  // The tags wholly in front of the lens, with their pixel bounds.
  std::vector<TagView> TagsInView(int camera) const;
  // The fraction of skin albedo left by the painted dots at pixel (x, y),
  // whose ray hits face triangle f (plane p0 p1 p2) at face-plane st: each
  // dot's anti-aliased coverage from its signed distance in pixels (the
  // skin distance over its rate of change per pixel step).
  double DotTransmission(int camera, int x, int y, int f, const Vec3& p0, const Vec3& p1,
                         const Vec3& p2, const Vec2& st) const;
  // Blends every tag plate nearer than *dist over the pixel (4 x 4
  // supersampled at the plate's edge and pattern cells).
  void CompositeTags(int camera, const std::vector<TagView>& tag_views,
                     const std::vector<Vec3>& lights, int x, int y, double* value,
                     double* dist, int* seen) const;
  double Albedo(const Vec2& st) const;
  // Construction steps: the dots' face-plane centres, metrics and grid
  // (lo, hi: the face plane's bounds); the triangles' grid; the skin albedo
  // texture; every pixel's ray and vignetting factor per camera.
  void IndexDots(const TriMesh& neutral, const Vec2& lo, const Vec2& hi);
  void IndexTriangles(const Vec2& lo, const Vec2& hi);
  void MakeAlbedoTexture(uint64_t seed, const Vec2& lo, const Vec2& hi);
  void PrecomputeRays();

  HelmetRig rig_;
  FootageRenderOptions options_;
  MatX3i F_;
  MatX2d st_;
  std::vector<std::vector<int>> vertex_faces_;
  std::vector<Marker> markers_;
  std::vector<Vec2> dot_st_;
  std::vector<Eigen::Matrix2d> dot_metric_;
  // Triangles by face-plane grid cell (tri_cell_ mm), for LocateFacePlane.
  double tri_cell_ = 1.0;
  Vec2 tri_origin_ = Vec2::Zero();
  int tri_w_ = 0, tri_h_ = 0;
  std::vector<std::vector<int>> tri_grid_;

  // Dots by face-plane grid cell (cell_ mm) for the per-pixel lookup.
  double cell_ = 4.0;
  Vec2 grid_origin_ = Vec2::Zero();
  int grid_w_ = 0, grid_h_ = 0;
  std::vector<std::vector<int>> dot_grid_;
  // Skin albedo variation texture over the face plane (texel_ mm).
  cv::Mat albedo_texture_;  // CV_32F, relative variation
  double texel_ = 0.5;
  Vec2 texture_origin_ = Vec2::Zero();
  std::vector<TagPattern> patterns_;
  std::vector<std::vector<Eigen::Vector3f>> bearings_;  // per camera: W*H unit rays
  std::vector<cv::Mat> vignette_;                         // per camera: CV_32F factor
};

}  // namespace hmc
