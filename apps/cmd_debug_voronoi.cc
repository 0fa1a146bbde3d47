// `hmc debug voronoi --actor DIR --out FILE.png [--bundle NAME]
// [--domain uv|geodesic] [--uv_resolution N] [--config FILE]`: the Voronoi
// cells of the bundle sites and one bundle's natural-neighbour weights
// (blending/natural_neighbour.h), drawn over the neutral's UV layout (left)
// and on a front render of the face (right). Cells get distinct pastel
// colours with dark borders; where the chosen bundle's weight is non-zero
// the weight is shown as a heat map (inferno, 0..1); sites are dots, the
// chosen one larger and ringed.
#include <algorithm>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include <opencv2/imgproc.hpp>
#include <spdlog/spdlog.h>

#include "apps/command.h"
#include "blending/natural_neighbour.h"
#include "blending/voronoi_uv.h"
#include "core/actor.h"
#include "core/color_map.h"
#include "core/image_io.h"
#include "core/logging.h"
#include "core/render_mesh.h"

namespace hmc {
namespace {

struct VoronoiArgs {
  std::string actor;
  std::string out;
  std::string bundle;
  int panel_px = 720;
  NaturalNeighbourOptions options;
};

// A distinct, light colour per cell (golden-ratio hue steps), RGB in [0, 1].
Vec3 CellColour(int k) {
  const double hue = std::fmod(0.13 + 0.618033988749895 * k, 1.0) * 6.0;
  const double x = 1.0 - std::abs(std::fmod(hue, 2.0) - 1.0);
  Vec3 rgb;
  switch (static_cast<int>(hue)) {
    case 0: rgb = {1, x, 0}; break;
    case 1: rgb = {x, 1, 0}; break;
    case 2: rgb = {0, 1, x}; break;
    case 3: rgb = {0, x, 1}; break;
    case 4: rgb = {x, 0, 1}; break;
    default: rgb = {1, 0, x}; break;
  }
  const double lightness = (k % 3 == 0) ? 0.55 : (k % 3 == 1 ? 0.7 : 0.62);
  return lightness * Vec3::Ones() + (1.0 - lightness) * rgb;
}

// The colour of a point with cell `k` and weight `w` of the chosen bundle.
Vec3 Colour(int k, double w) {
  if (w > 0) return MapColor(ColorMap::kInferno, 0.15 + 0.85 * w);
  return CellColour(k);
}

cv::Vec3b ToBgr(const Vec3& rgb) {
  auto c = [](double x) {
    return static_cast<uchar>(std::clamp(std::lround(255.0 * x), 0L, 255L));
  };
  return cv::Vec3b(c(rgb[2]), c(rgb[1]), c(rgb[0]));
}

int RunDebugVoronoi(VoronoiArgs& args, OptionBinding& binding) {
  binding.Apply();
  RequireValid(args.options, "natural-neighbour");
  StageTimer timer("debug voronoi");
  PrepareOutputPaths({{args.out, "--out"}}, {{args.actor, "--actor"}});
  const Actor actor = LoadActor(args.actor);
  if (actor.markers.empty()) ThrowInputError(actor.dir, 0, "the actor has no markers");
  std::vector<SurfacePoint> sites;
  for (const Marker& marker : actor.markers) sites.push_back(marker.point);
  const MatX2d site_uv = SiteUVs(actor.neutral, sites);
  // Default bundle: the one nearest the middle of the sites in UV.
  int chosen = 0;
  const Vec2 middle = site_uv.colwise().mean().transpose();
  for (int k = 1; k < static_cast<int>(sites.size()); ++k) {
    if ((site_uv.row(k).transpose() - middle).norm() <
        (site_uv.row(chosen).transpose() - middle).norm()) {
      chosen = k;
    }
  }
  if (!args.bundle.empty()) {
    chosen = actor.FindMarker(args.bundle);
    if (chosen < 0) {
      ThrowInputError(actor.dir, 0, "no marker named '{}' in the actor package",
                      args.bundle);
    }
  }
  const NaturalNeighbourWeights nn =
      ComputeNaturalNeighbourWeights(actor.neutral, sites, args.options);
  const int num_vertices = actor.NumVertices();
  Eigen::VectorXd lambda = Eigen::VectorXd::Zero(num_vertices);
  for (int v = 0; v < num_vertices; ++v) lambda[v] = nn.weights.coeff(v, chosen);

  // UV panel: the cells of the chosen domain, per pixel of a display raster.
  const TriMesh& mesh = actor.neutral;
  const UvRaster raster = RasteriseUvLayout(mesh, args.panel_px - 40);
  std::vector<int> label(raster.face.size(), -1);
  if (args.options.domain == "uv") {
    label = ComputeUvVoronoi(raster, site_uv).label;
  }
  std::vector<double> weight(raster.face.size(), 0.0);
  for (size_t i = 0; i < raster.face.size(); ++i) {
    const int f = raster.face[i];
    if (f < 0) continue;
    int corner = 0;
    raster.bary[i].maxCoeff(&corner);
    if (args.options.domain != "uv") label[i] = nn.cell[mesh.F(f, corner)];
    for (int c = 0; c < 3; ++c) weight[i] += raster.bary[i][c] * lambda[mesh.F(f, c)];
  }
  cv::Mat uv_panel(args.panel_px, args.panel_px, CV_8UC3, cv::Scalar(38, 38, 38));
  const int offset_x = (args.panel_px - raster.width) / 2;
  const int offset_y = (args.panel_px - raster.height) / 2;
  auto to_image = [&](int x, int y) {  // raster y grows with v: flip
    return cv::Point(offset_x + x, offset_y + raster.height - 1 - y);
  };
  for (int y = 0; y < raster.height; ++y) {
    for (int x = 0; x < raster.width; ++x) {
      const int i = raster.Index(x, y);
      if (!raster.InDomain(i)) continue;
      bool border = false;
      if (x + 1 < raster.width && raster.InDomain(i + 1)) border |= label[i + 1] != label[i];
      if (y + 1 < raster.height && raster.InDomain(i + raster.width)) {
        border |= label[i + raster.width] != label[i];
      }
      const Vec3 rgb = border ? Vec3(0.12, 0.12, 0.12) : Colour(label[i], weight[i]);
      uv_panel.at<cv::Vec3b>(to_image(x, y)) = ToBgr(rgb);
    }
  }
  for (int k = 0; k < static_cast<int>(sites.size()); ++k) {
    const Vec2 p = (site_uv.row(k).transpose() - raster.origin) / raster.pixel_size;
    const cv::Point c = to_image(static_cast<int>(p.x()), static_cast<int>(p.y()));
    if (k == chosen) {
      cv::circle(uv_panel, c, 7, cv::Scalar(255, 255, 255), 2, cv::LINE_AA);
      cv::circle(uv_panel, c, 4, cv::Scalar(40, 220, 40), -1, cv::LINE_AA);
    } else {
      cv::circle(uv_panel, c, 3, cv::Scalar(20, 20, 20), -1, cv::LINE_AA);
    }
  }

  // Face panel: the same colouring per vertex; borders darken the vertices
  // that have a neighbour in another cell.
  MatX3d vertex_rgb(num_vertices, 3);
  std::vector<char> border(num_vertices, 0);
  for (int f = 0; f < mesh.NumFaces(); ++f) {
    for (int c = 0; c < 3; ++c) {
      const int a = mesh.F(f, c), b = mesh.F(f, (c + 1) % 3);
      if (nn.cell[a] != nn.cell[b]) border[a] = border[b] = 1;
    }
  }
  for (int v = 0; v < num_vertices; ++v) {
    const Vec3 rgb = Colour(nn.cell[v], lambda[v]);
    vertex_rgb.row(v) = (border[v] ? 0.35 * rgb : rgb).transpose();
  }
  MeshRenderOptions render;
  render.width = args.panel_px * 4 / 5;
  render.height = args.panel_px;
  const cv::Mat face_panel = RenderMesh(mesh, render, vertex_rgb);

  const std::string name = actor.markers[chosen].name;
  const cv::Mat image = ComposeLabelledPanels(
      {WithColorBar(uv_panel, ColorMap::kInferno, 0.0, 1.0, "weight"), face_panel},
      {fmt::format("UV layout: {} cells ({}), weights of '{}'",
                   sites.size(), args.options.domain, name),
       "front render, same colouring"});
  WritePng(args.out, image);
  int support = 0;
  for (int v = 0; v < num_vertices; ++v) support += lambda[v] > 0;
  spdlog::info("wrote {}: {} sites, bundle '{}' ({} natural neighbours) has "
               "non-zero weight on {} of {} vertices",
               args.out, sites.size(), name, nn.site_neighbours[chosen].size(),
               support, num_vertices);
  return 0;
}

}  // namespace

HMC_COMMAND(DebugVoronoi, "debug", "voronoi",
            "Picture the Voronoi cells of the bundles and one bundle's "
            "natural-neighbour weights") {
  auto args = std::make_shared<VoronoiArgs>();
  app->add_option("--actor", args->actor, "Actor package folder")->required();
  app->add_option("--out", args->out, "Output PNG file")->required();
  app->add_option("--bundle", args->bundle,
                  "Marker whose weights to show (default: the one nearest the middle of the markers in UV)");
  app->add_option("--panel", args->panel_px, "Panel height (px)")
      ->capture_default_str();
  auto binding = BindOptions(app, &args->options);
  return [args, binding] { return RunDebugVoronoi(*args, *binding); };
}

}  // namespace hmc
