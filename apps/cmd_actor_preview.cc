// `hmc actor preview DIR --out FILE.png [--shape NAME]... [--width W]
// [--height H] [--yaw DEG]`: shaded pictures of an actor's neutral or of
// named shapes, side by side with each name written below its panel. All
// panels share one camera (framing the union of their bounding boxes), so
// they line up and differences between shapes show.
#include <memory>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "apps/command.h"
#include "core/actor.h"
#include "core/image_io.h"
#include "core/logging.h"
#include "core/render_mesh.h"

namespace hmc {
namespace {

struct PreviewArgs {
  std::string dir;
  std::string out;
  std::vector<std::string> shapes;
  MeshRenderOptions render;
  bool orthographic = false;
};

// Positions of "neutral" or a named shape; throws InputError naming the
// package when the shape does not exist.
MatX3d PanelPositions(const Actor& actor, const std::string& name) {
  if (name == "neutral") return actor.neutral.V;
  const int index = actor.FindShape(name);
  if (index < 0) {
    std::string known;
    for (size_t i = 0; i < actor.shapes.size() && i < 12; ++i) {
      known += (i ? ", " : "") + actor.shapes[i].name;
    }
    if (actor.shapes.size() > 12) known += ", ...";
    ThrowInputError(actor.dir, 0,
                    "no shape named '{}' in the actor package ({} shapes: {})",
                    name, actor.shapes.size(), known.empty() ? "none" : known);
  }
  return actor.ShapePositions(index);
}

int RunPreview(const PreviewArgs& args) {
  StageTimer timer("actor preview");
  MeshRenderOptions options = args.render;
  options.perspective = !args.orthographic;
  RequireValid(options, "preview");
  PrepareOutputPaths({{args.out, "--out"}}, {{args.dir, "DIR"}});
  const Actor actor = LoadActor(args.dir);
  const std::vector<std::string> names =
      args.shapes.empty() ? std::vector<std::string>{"neutral"} : args.shapes;

  // Resolve every panel before rendering: a bad name writes nothing.
  std::vector<MatX3d> positions;
  Eigen::Matrix<double, 2, 3> box;
  for (size_t i = 0; i < names.size(); ++i) {
    positions.push_back(PanelPositions(actor, names[i]));
    const Eigen::Matrix<double, 2, 3> panel_box = BoundingBox(positions.back());
    if (i == 0) {
      box = panel_box;
    } else {
      box.row(0) = box.row(0).cwiseMin(panel_box.row(0));
      box.row(1) = box.row(1).cwiseMax(panel_box.row(1));
    }
  }
  options.frame_box = box;

  std::vector<cv::Mat> panels;
  TriMesh mesh = actor.neutral;
  for (size_t i = 0; i < names.size(); ++i) {
    mesh.V = positions[i];
    panels.push_back(RenderMesh(mesh, options));
    spdlog::debug("rendered panel '{}'", names[i]);
  }
  const cv::Mat image = ComposeLabelledPanels(panels, names);
  WritePng(args.out, image);
  spdlog::info("wrote {} ({} panel{}, {} x {} px)", args.out, panels.size(),
               panels.size() == 1 ? "" : "s", image.cols, image.rows);
  return 0;
}

}  // namespace

HMC_COMMAND(ActorPreview, "actor", "preview",
            "Render shaded pictures of the neutral or of named shapes") {
  auto args = std::make_shared<PreviewArgs>();
  app->add_option("dir", args->dir, "Actor package folder")->required();
  app->add_option("--out", args->out, "Output PNG file")->required();
  app->add_option("--shape", args->shapes,
                  "Shape to show (repeatable; 'neutral' names the neutral; "
                  "default: the neutral)")
      ->allow_extra_args(false);  // one name per --shape
  app->add_option("--width", args->render.width, "Panel width (px)")
      ->capture_default_str();
  app->add_option("--height", args->render.height, "Panel height (px)")
      ->capture_default_str();
  app->add_option("--yaw", args->render.yaw_deg,
                  "Turn the view about the vertical axis (deg; + shows more "
                  "of the actor's left)")
      ->capture_default_str();
  app->add_option("--pitch", args->render.pitch_deg,
                  "Raise the camera, looking down (deg)")
      ->capture_default_str();
  app->add_option("--supersample", args->render.supersample,
                  "Anti-aliasing: s x s samples per pixel")
      ->capture_default_str();
  app->add_flag("--orthographic", args->orthographic,
                "Orthographic instead of pinhole camera");
  app->add_flag("--wireframe", args->render.wireframe, "Draw triangle edges");
  return [args] { return RunPreview(*args); };
}

}  // namespace hmc
