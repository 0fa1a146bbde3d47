// Shaded previews of a face mesh (`hmc actor preview`, debug pictures):
// the mesh seen from the front (+z toward the viewer, +y up, so the actor's
// left, +x, is on the image's right), optionally turned by a yaw angle for a
// three-quarter view. Smooth (per-vertex normal) Lambert shading plus a
// little Blinn-Phong specular from a key and a fill light fixed to the
// camera; supersampled for anti-aliasing. Built on core/raster.h.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "core/color_map.h"
#include "core/mesh.h"
#include "core/types.h"

namespace hmc {

struct MeshRenderOptions {
  int width = 480;          // output image size (px)
  int height = 600;
  double yaw_deg = 0;       // camera turned about the vertical axis through
                            // the box centre; + moves it toward +x (the
                            // actor's left)
  double pitch_deg = 0;     // + moves the camera up, looking down
  bool perspective = true;  // pinhole camera; false: orthographic
  double distance = 3.0;    // pinhole camera distance from the box centre,
                            // in radii of the box's bounding sphere
  double margin = 0.06;     // fraction of the frame kept free on each side
  int supersample = 2;      // s x s samples per pixel, box-filtered
  bool wireframe = false;   // darken triangle edges
  Eigen::Vector3d base_rgb{0.80, 0.68, 0.60};       // skin-like (sRGB 0-1)
  Eigen::Vector3d background_rgb{0.15, 0.15, 0.15};  // dark grey (sRGB 0-1)
  // Head-space box to frame (row 0 min, row 1 max); unset: the mesh's own
  // bounding box. Panels of several shapes share one so they line up.
  std::optional<Eigen::Matrix<double, 2, 3>> frame_box;

  bool Check() const;  // logs the offending field
};

// Renders `mesh` to an 8-bit BGR image (options.width x options.height).
// vertex_rgb: V x 3 per-vertex colours (sRGB in [0, 1]); empty: base_rgb.
// Triangles are drawn from both sides (the inside of the mouth shows).
// Requires options.Check().
cv::Mat RenderMesh(const TriMesh& mesh, const MeshRenderOptions& options,
                   const MatX3d& vertex_rgb = MatX3d());

// Renders a per-vertex scalar field (V values, e.g. error in mm) through a
// colour map over [lo, hi] (clamped), shaded like RenderMesh.
cv::Mat RenderMeshScalars(const TriMesh& mesh, const Eigen::VectorXd& values,
                          double lo, double hi, ColorMap map,
                          const MeshRenderOptions& options);

// Panels (CV_8UC3, same height) side by side, each with its label written
// in a strip below it.
cv::Mat ComposeLabelledPanels(const std::vector<cv::Mat>& panels,
                              const std::vector<std::string>& labels);

}  // namespace hmc
