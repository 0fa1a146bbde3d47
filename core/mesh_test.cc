#include "core/mesh.h"

#include <random>

#include <gtest/gtest.h>

namespace hmc {
namespace {

// Two triangles forming the unit square, with a UV seam at vertex 2.
TriMesh Square() {
  TriMesh mesh;
  mesh.V.resize(4, 3);
  mesh.V << 0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0;
  mesh.F.resize(2, 3);
  mesh.F << 0, 1, 2, 0, 2, 3;
  mesh.UV.resize(5, 2);
  mesh.UV << 0, 0, 1, 0, 1, 1, 0, 1, 0.9, 0.9;
  mesh.FUV.resize(2, 3);
  mesh.FUV << 0, 1, 2, 0, 4, 3;
  return mesh;
}

TEST(MeshTest, SurfacePointsInterpolateLinearly) {
  const TriMesh mesh = Square();
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int i = 0; i < 100; ++i) {
    SurfacePoint point;
    point.face = i % 2;
    const double a = unit(rng), b = unit(rng) * (1 - a);
    point.bary = Vec3(a, b, 1 - a - b);
    // An affine map of the positions maps the point the same way.
    const Mat3 linear = Mat3::Random();
    const Vec3 shift = Vec3::Random();
    MatX3d moved = (mesh.V * linear.transpose()).rowwise() + shift.transpose();
    const Vec3 x = EvaluateSurfacePoint(point, mesh.F, mesh.V);
    EXPECT_LT((EvaluateSurfacePoint(point, mesh.F, moved) - (linear * x + shift)).norm(),
              1e-12);
  }
  for (int v = 0; v < 4; ++v) {
    const SurfacePoint at = SurfacePointAtVertex(mesh.F, v);
    EXPECT_EQ(EvaluateSurfacePoint(at, mesh.F, mesh.V), Vec3(mesh.V.row(v)));
  }
}

TEST(MeshTest, PerVertexUvTakesFirstCorner) {
  const MatX2d uv = PerVertexUVs(Square());
  ASSERT_EQ(uv.rows(), 4);
  EXPECT_EQ(Vec2(uv.row(2)), Vec2(1, 1));  // First corner of vertex 2.
  EXPECT_EQ(Vec2(uv.row(3)), Vec2(0, 1));
}

TEST(MeshTest, NormalsOfFlatSquarePointUp) {
  const TriMesh mesh = Square();
  const MatX3d n = VertexNormals(mesh.V, mesh.F);
  for (int v = 0; v < 4; ++v) EXPECT_LT((Vec3(n.row(v)) - Vec3::UnitZ()).norm(), 1e-12);
  const auto box = BoundingBox(mesh.V);
  EXPECT_EQ(Vec3(box.row(0)), Vec3(0, 0, 0));
  EXPECT_EQ(Vec3(box.row(1)), Vec3(1, 1, 0));
}

}  // namespace
}  // namespace hmc
