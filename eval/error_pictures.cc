#include "eval/error_pictures.h"

#include <limits>

#include "core/raster.h"
#include "core/render_mesh.h"

namespace hmc {

cv::Mat ErrorPicture(const TriMesh& neutral, const MatX3d& truth,
                     const MatX3d& recon, const Eigen::VectorXd& vertex_error,
                     const std::array<std::string, 3>& labels,
                     double heat_max_mm, ColorMap color_map,
                     const PictureOptions& picture) {
  TriMesh t = neutral, r = neutral;
  t.V = truth;
  r.V = recon;
  Eigen::Matrix<double, 2, 3> box = BoundingBox(t.V);
  const Eigen::Matrix<double, 2, 3> rbox = BoundingBox(r.V);
  box.row(0) = box.row(0).cwiseMin(rbox.row(0));
  box.row(1) = box.row(1).cwiseMax(rbox.row(1));
  MeshRenderOptions ro;
  ro.width = picture.image_width;
  ro.height = picture.image_height;
  ro.frame_box = box;
  const cv::Mat panels = ComposeLabelledPanels(
      {RenderMesh(t, ro), RenderMesh(r, ro),
       RenderMeshScalars(r, vertex_error, 0.0, heat_max_mm, color_map, ro)},
      {labels[0], labels[1], labels[2]});
  return WithColorBar(panels, color_map, 0.0, heat_max_mm, "mm");
}

cv::Mat UvMap(const TriMesh& mesh, const Eigen::VectorXd& values, int size) {
  cv::Mat image(size, size, CV_32F,
                cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
  if (!mesh.HasUVs()) return image;
  Eigen::VectorXd uv_values(mesh.UV.rows());
  uv_values.setZero();
  for (int t = 0; t < mesh.NumFaces(); ++t) {
    for (int c = 0; c < 3; ++c)
      uv_values[mesh.FUV(t, c)] = values[mesh.F(t, c)];
  }
  MatX3d screen(mesh.UV.rows(), 3);
  for (int i = 0; i < mesh.UV.rows(); ++i) {
    screen.row(i) << mesh.UV(i, 0) * size - 0.5,
        (1 - mesh.UV(i, 1)) * size - 0.5, 0.0;
  }
  RasterOptions ro;
  ro.width = size;
  ro.height = size;
  const RasterBuffer buffer =
      Rasterize(screen, Eigen::VectorXd(), mesh.FUV, ro);
  for (int y = 0; y < size; ++y) {
    for (int x = 0; x < size; ++x) {
      const int index = buffer.Index(x, y);
      if (!buffer.Covered(index)) continue;
      image.at<float>(y, x) = static_cast<float>(
          InterpolateAt(buffer, index, mesh.FUV, uv_values)(0));
    }
  }
  return image;
}

}  // namespace hmc
