// The pictures of a reconstruction's error that `hmc eval` and
// `hmc experiment` write: truth | reconstruction | error heat-map panels
// (core/render_mesh.h) with a colour bar, and per-vertex values rasterised
// over the UV layout (core/raster.h) for the EXR error maps.
#pragma once

#include <array>
#include <string>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "core/color_map.h"
#include "core/mesh.h"
#include "eval/picture_options.h"

namespace hmc {

// Three panels rendered in one frame box (the union of both meshes'
// bounding boxes): the truth, the reconstruction and the reconstruction
// coloured by `vertex_error` on [0, heat_max_mm] (mm), under `labels`, with
// a colour bar in mm. truth, recon: V x 3 positions on `neutral`'s
// triangles (mm). Image size from `picture` (image_width x image_height per
// panel).
cv::Mat ErrorPicture(const TriMesh& neutral, const MatX3d& truth,
                     const MatX3d& recon, const Eigen::VectorXd& vertex_error,
                     const std::array<std::string, 3>& labels,
                     double heat_max_mm, ColorMap color_map,
                     const PictureOptions& picture);

// Per-vertex values rasterised over the UV layout of `mesh`: size x size,
// CV_32F, v = 1 at the top row; NaN where no triangle covers the pixel (all
// NaN for a mesh without UVs).
cv::Mat UvMap(const TriMesh& mesh, const Eigen::VectorXd& values, int size);

}  // namespace hmc
