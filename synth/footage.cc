// The footage renderer's options, its precomputation (dots, triangles and
// albedo on the face plane, the pixels' rays) and Render, the camera's step
// (synth/footage.h, step 3); the shading is in synth/footage_shading.cc, the
// dots' and tags' ground truth in synth/footage_truth.cc.
#include "synth/footage.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Eigenvalues>
#include <opencv2/imgproc.hpp>
#include <spdlog/spdlog.h>

#include "core/error.h"
#include "core/parallel.h"
#include "synth/sensor_noise.h"
#include "synth/synth_random.h"

namespace hmc {

void FootageRenderOptions::Register(OptionFields* fields) {
  fields->SetGroup("render");
  fields->Add("dot_radius", &dot_radius, "painted dot radius on the skin (mm)")
      .Above(0.1).Below(20);
  fields->Add("dot_albedo", &dot_albedo, "reflectance of the dot paint").In(0, 1);
  fields->Add("skin_albedo", &skin_albedo, "mean skin reflectance").In(0, 1);
  fields->Add("albedo_variation", &albedo_variation,
              "relative amplitude of the skin's albedo variation")
      .AtLeast(0).Below(1);
  fields->Add("tag_white", &tag_white, "reflectance of the tags' white").In(0, 1);
  fields->Add("tag_black", &tag_black, "reflectance of the tags' black").In(0, 1);
  fields->Add("background", &background, "radiance where nothing is hit").In(0, 1);
  fields->Add("ambient", &ambient, "ambient light (fraction of full exposure)").In(0, 2);
  fields->Add("light_power", &light_power,
              "each head light's irradiance at 170 mm, head-on (fraction of full exposure)")
      .In(0, 10);
  fields->Add("light_offset", &light_offset, "head light offset beside each camera (mm)")
      .AtLeast(0).Below(200);
  fields->Add("exposure", &exposure, "gain on the radiance before the sensor (1 = as lit)")
      .Above(0).AtMost(10);
  fields->Add("exposure_drift", &exposure_drift,
              "relative change of the exposure from the first frame to the last (linear; -0.2 = "
              "20% darker at the end)")
      .Above(-1).AtMost(10);
  fields->Add("specular", &specular,
              "skin's specular (Blinn-Phong) reflectance (0 = matte; the dots' paint stays matte)")
      .In(0, 1);
  fields->Add("shininess", &shininess, "Blinn-Phong exponent of the skin's highlights").In(1, 1000);
  fields->Add("vignetting", &vignetting, "darkening at the image corner (0 = off)").In(0, 1);
  fields->Add("read_noise", &read_noise, "std of the sensor read noise (8-bit levels; 0 = off)")
      .AtLeast(0).Below(50);
  fields->Add("shot_noise", &shot_noise, "shot-noise variance per level of signal (0 = off)")
      .AtLeast(0).Below(10);
  fields->Add("motion_blur_samples", &motion_blur_samples,
              "sub-frame samples over the shutter (1 = off)")
      .In(1, 64);
  fields->Add("shutter", &shutter, "exposure as a fraction of the frame interval")
      .Above(0).AtMost(1);
  fields->Add("defocus_px", &defocus_px, "Gaussian defocus blur sigma (px; 0 = off)")
      .AtLeast(0).Below(20);
  fields->Add("max_edge_error_px", &max_edge_error_px, "fisheye subdivision tolerance (px)")
      .Above(0.001).AtMost(2);
  fields->Add("transfer", &transfer,
              "8-bit encoding: linear | srgb (the sRGB curve, as most cameras write PNG)")
      .OneOf({"linear", "srgb"});
  fields->SetGroup("");
}

bool FootageRenderOptions::Check() const {
  CHECK_OPTION_LIMITS();
  return true;
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

}  // namespace hmc
