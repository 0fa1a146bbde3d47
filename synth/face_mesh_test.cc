#include "synth/face_mesh.h"

#include <set>
#include <utility>

#include <gtest/gtest.h>

namespace hmc {
namespace {

FaceMesh SmallFace(uint64_t seed = 1) {
  return BuildFaceMesh(DrawFaceProportions(seed, 0.04), 64, 52);
}

TEST(FaceMeshTest, DefaultGridHasAtLeast50kVerticesAndAdultSize) {
  const FaceMesh face = BuildFaceMesh(DrawFaceProportions(1, 0.04), 256, 200);
  EXPECT_GE(face.mesh.NumVertices(), 50000);
  // Width of the head ~ 140 mm; chin to hairline ~ 190 mm: the hairline is
  // the top row, the chin the lowest point of the front profile (s = 0)
  // before the surface turns back under the jaw.
  const auto box = BoundingBox(face.mesh.V);
  const double width = box(1, 0) - box(0, 0);
  EXPECT_GT(width, 125.0);
  EXPECT_LT(width, 160.0);
  double chin_t = 0, best_z = -1e9;
  for (int v = 0; v < face.mesh.NumVertices(); ++v) {
    if (std::abs(face.st(v, 0)) > 1.0 || face.st(v, 1) > -70) continue;
    // The chin's lowest point: where the profile leans furthest forward
    // below the mouth.
    if (face.mesh.V(v, 2) > best_z) {
      best_z = face.mesh.V(v, 2);
      chin_t = face.st(v, 1);
    }
  }
  const double face_height = kTMax - (chin_t - 12.0);  // chin pad to hairline
  EXPECT_GT(face_height, 170.0);
  EXPECT_LT(face_height, 210.0);
  // The nose tip is the most forward point of the face.
  int tip = 0;
  face.mesh.V.col(2).maxCoeff(&tip);
  EXPECT_NEAR(face.st(tip, 0), 0.0, 2.0);
  EXPECT_NEAR(face.st(tip, 1), face.proportions.nose_tip_t, 6.0);
}

TEST(FaceMeshTest, UVsInUnitSquareOnePerVertex) {
  const FaceMesh face = SmallFace();
  ASSERT_EQ(face.mesh.UV.rows(), face.mesh.NumVertices());
  EXPECT_GE(face.mesh.UV.minCoeff(), 0.0);
  EXPECT_LE(face.mesh.UV.maxCoeff(), 1.0);
  EXPECT_EQ(face.mesh.FUV, face.mesh.F);
  // UV and face-plane coordinates agree.
  for (int v = 0; v < face.mesh.NumVertices(); v += 37) {
    const Vec2 st = FacePlaneFromUV(face.mesh.UV.row(v).transpose());
    EXPECT_NEAR((st - face.st.row(v).transpose()).norm(), 0.0, 1e-9);
  }
}

TEST(FaceMeshTest, TrianglesNonDegenerateAndOutward) {
  for (const auto& [gu, gv] : {std::pair{40, 32}, std::pair{64, 52}, std::pair{256, 200}}) {
    const FaceMesh face = BuildFaceMesh(DrawFaceProportions(3, 0.04), gu, gv);
    const MatX3d& V = face.mesh.V;
    double min_area = 1e9;
    int inward = 0;
    for (int f = 0; f < face.mesh.NumFaces(); ++f) {
      const Vec3 a = V.row(face.mesh.F(f, 0)), b = V.row(face.mesh.F(f, 1)),
                 c = V.row(face.mesh.F(f, 2));
      const Vec3 n = (b - a).cross(c - a);
      min_area = std::min(min_area, 0.5 * n.norm());
      // Outward = away from the head's vertical axis (a radial height field).
      const Vec3 centroid = (a + b + c) / 3.0;
      const Vec3 radial(centroid.x(), 0.0, centroid.z());
      if (n.dot(radial) <= 0) ++inward;
    }
    EXPECT_GT(min_area, 1e-3 * face.row_spacing * face.row_spacing) << gu << "x" << gv;
    EXPECT_EQ(inward, 0) << gu << "x" << gv;
  }
}

TEST(FaceMeshTest, MouthSlitSeparatesTheLips) {
  for (const auto& [gu, gv] : {std::pair{40, 32}, std::pair{256, 200}}) {
    const FaceMesh face = BuildFaceMesh(DrawFaceProportions(5, 0.04), gu, gv);
    EXPECT_LT(face.mesh.NumFaces(), 2 * (gu - 1) * (gv - 1));
    // The rows just above and below the slit share no triangle near the
    // middle of the mouth.
    std::set<std::pair<int, int>> edges;
    for (int f = 0; f < face.mesh.NumFaces(); ++f) {
      for (int i = 0; i < 3; ++i) {
        edges.insert({face.mesh.F(f, i), face.mesh.F(f, (i + 1) % 3)});
      }
    }
    int crossing = 0, slit_columns = 0;
    for (int v = 0; v < face.mesh.NumVertices(); ++v) {
      const double s = face.st(v, 0), t = face.st(v, 1);
      if (std::abs(t - (face.proportions.mouth_t - 0.5 * face.row_spacing)) > 1e-6) continue;
      if (std::abs(s) > 0.5 * face.proportions.mouth_half_width) continue;
      ++slit_columns;
      for (int du = -1; du <= 1; ++du) {
        const int w = v + face.grid_u + du;  // a vertex of the row above
        if (edges.count({v, w}) || edges.count({w, v})) ++crossing;
      }
    }
    EXPECT_GT(slit_columns, 0) << gu << "x" << gv;
    EXPECT_EQ(crossing, 0) << gu << "x" << gv;
  }
}

TEST(FaceMeshTest, JawWeightsSmoothInUnitRange) {
  const FaceMesh face = BuildFaceMesh(DrawFaceProportions(2, 0.04), 256, 200);
  const Eigen::VectorXd& w = face.jaw_rig.weights;
  ASSERT_EQ(w.size(), face.mesh.NumVertices());
  EXPECT_GE(w.minCoeff(), 0.0);
  EXPECT_LE(w.maxCoeff(), 1.0);
  const FaceProportions& p = face.proportions;
  for (int v = 0; v < face.mesh.NumVertices(); ++v) {
    const double s = face.st(v, 0), t = face.st(v, 1);
    if (std::abs(s) < 12 && t < p.mouth_t - 0.4 * face.row_spacing && t > p.chin_t - 10) {
      EXPECT_EQ(w[v], 1.0) << "chin / lower lip " << s << " " << t;
    }
    if ((t > p.mouth_t + 0.4 * face.row_spacing && std::abs(s) < 10) ||
        (t > p.nose_tip_t - 5 && std::abs(s) < 45)) {
      EXPECT_EQ(w[v], 0.0) << "upper lip and above " << s << " " << t;
    }
  }
  // Smooth falloff: the weight changes little across any edge of the mesh,
  // except on the lips beside the slit and at the corners, where it goes from a step (across
  // the removed slit, in the middle) to a soft ramp (at the corners).
  double max_jump = 0, max_jump_lips = 0;
  for (int f = 0; f < face.mesh.NumFaces(); ++f) {
    for (int i = 0; i < 3; ++i) {
      const int a = face.mesh.F(f, i), b = face.mesh.F(f, (i + 1) % 3);
      // Per mm of the face plane.
      const double jump = std::abs(w[a] - w[b]) /
                          (face.st.row(a) - face.st.row(b)).norm();
      const bool on_lips =
          std::abs(face.st(a, 0)) < p.mouth_half_width + 4 &&
          std::abs(face.st(a, 1) - p.mouth_t) < 3 * face.row_spacing;
      (on_lips ? max_jump_lips : max_jump) =
          std::max(on_lips ? max_jump_lips : max_jump, jump);
    }
  }
  EXPECT_LT(max_jump, 0.15);       // per mm: a ramp over >= ~7 mm
  EXPECT_LT(max_jump_lips, 0.4);
  // The pivot is behind and above the mouth corners.
  EXPECT_GT(face.jaw_rig.pivot.y(), p.mouth_t);
  EXPECT_LT(face.jaw_rig.pivot.z(), 40.0);
}

TEST(FaceMeshTest, DeterministicBySeed) {
  const FaceMesh a = SmallFace(7), b = SmallFace(7), c = SmallFace(8);
  EXPECT_EQ(a.mesh.V, b.mesh.V);
  EXPECT_EQ(a.mesh.F, b.mesh.F);
  EXPECT_EQ(a.jaw_rig.weights, b.jaw_rig.weights);
  EXPECT_GT((a.mesh.V - c.mesh.V).cwiseAbs().maxCoeff(), 0.5);
  // No jitter: every seed gives the average face.
  const FaceMesh d = BuildFaceMesh(DrawFaceProportions(11, 0.0), 40, 32);
  const FaceMesh e = BuildFaceMesh(DrawFaceProportions(12, 0.0), 40, 32);
  EXPECT_EQ(d.mesh.V, e.mesh.V);
}

TEST(FaceMeshTest, SurfacePointRoundTrip) {
  const FaceMesh face = SmallFace();
  int found = 0;
  for (double s = -60; s <= 60; s += 7.3) {
    for (double t = -100; t <= 90; t += 6.1) {
      const SurfacePoint point = FaceSurfacePoint(face, Vec2(s, t));
      if (point.face < 0) continue;  // in the mouth slit
      ++found;
      EXPECT_NEAR(point.bary.sum(), 1.0, 1e-12);
      EXPECT_GE(point.bary.minCoeff(), -1e-12);
      Vec2 st = Vec2::Zero();
      for (int i = 0; i < 3; ++i) {
        st += point.bary[i] * face.st.row(face.mesh.F(point.face, i)).transpose();
      }
      EXPECT_NEAR((st - Vec2(s, t)).norm(), 0.0, 1e-9);
    }
  }
  EXPECT_GT(found, 250);
  EXPECT_EQ(FaceSurfacePoint(face, Vec2(0, face.proportions.mouth_t)).face, -1);
  EXPECT_EQ(FaceSurfacePoint(face, Vec2(0, kTMax + 5)).face, -1);
}

}  // namespace
}  // namespace hmc
