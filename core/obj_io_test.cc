#include "core/obj_io.h"

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <random>
#include <string>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "core/error.h"
#include "core/file_util.h"
#include "core/temp_dir.h"

namespace hmc {
namespace {

namespace fs = std::filesystem;

// A quad, a pentagon and a triangle as a DCC writes them: normals, groups,
// materials, smoothing, comments, CRLF line ends, and a UV seam (vertex 2
// has UV 2 in the quad and UV 6 in the triangle).
constexpr char kDccObj[] =
    "# exported\r\n"
    "mtllib a.mtl\r\n"
    "o face\r\n"
    "v 0 0 0\r\n"
    "v 1 0 0\r\n"
    "v 1 1 0\r\n"
    "v 0 1 0\r\n"
    "v 2 0.5 0   # trailing comment\r\n"
    "v 2 1.5 0\r\n"
    "v 0.5 2 0\r\n"
    "vt 0 0\nvt 0.5 0\nvt 0.5 0.5\nvt 0 0.5\nvt 1 0.25\nvt 1 0.75\n"
    "vt 0.9 0.9\nvt 0.25 1\n"
    "vn 0 0 1\n"
    "g face_geo\n"
    "usemtl skin\n"
    "s 1\n"
    "f 1/1/1 2/2/1 3/3/1 4/4/1\n"
    "s off\n"
    "f -6/2/1 -3/5/1 -2/6/1 -5/3/1\n"  // relative indices: 2 5 6 3
    "f 4/4 3/7 7/8\n";

TEST(ObjIo, ReadsPolygonsSeamsAndRelativeIndices) {
  ObjPolygons polygons;
  const TriMesh mesh = ParseObj(kDccObj, "dcc.obj", {}, &polygons);
  ASSERT_EQ(mesh.NumVertices(), 7);
  ASSERT_EQ(mesh.NumFaces(), 2 + 2 + 1);
  ASSERT_EQ(mesh.UV.rows(), 8);
  ASSERT_EQ(polygons.NumPolygons(), 3);
  EXPECT_EQ(polygons.corners, (std::vector<int>{4, 4, 3}));
  EXPECT_EQ(polygons.first_triangle, (std::vector<int>{0, 2, 4}));
  // Fans from the first corner.
  EXPECT_EQ(mesh.F.row(0), Eigen::RowVector3i(0, 1, 2));
  EXPECT_EQ(mesh.F.row(1), Eigen::RowVector3i(0, 2, 3));
  EXPECT_EQ(mesh.F.row(2), Eigen::RowVector3i(1, 4, 5));
  EXPECT_EQ(mesh.F.row(3), Eigen::RowVector3i(1, 5, 2));
  EXPECT_EQ(mesh.FUV.row(3), Eigen::RowVector3i(1, 5, 2));
  EXPECT_EQ(mesh.F.row(4), Eigen::RowVector3i(3, 2, 6));
  // The seam: vertex 2 keeps both of its UVs.
  EXPECT_EQ(mesh.FUV(0, 2), 2);
  EXPECT_EQ(mesh.FUV(4, 1), 6);
  EXPECT_DOUBLE_EQ(mesh.V(4, 1), 0.5);
  EXPECT_DOUBLE_EQ(mesh.UV(6, 0), 0.9);
}

TEST(ObjIo, ScalesPositionsNotUvs) {
  ObjReadOptions options;
  options.scale = 10;
  const TriMesh unscaled = ParseObj(kDccObj, "dcc.obj");
  const TriMesh scaled = ParseObj(kDccObj, "dcc.obj", options);
  EXPECT_TRUE(scaled.V.isApprox(10 * unscaled.V));
  EXPECT_EQ(scaled.UV, unscaled.UV);
  EXPECT_EQ(scaled.F, unscaled.F);
}

TEST(ObjIo, ReadsMeshWithoutUvsUnlessRequired) {
  const std::string text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//1\n";
  const TriMesh mesh = ParseObj(text, "plain.obj");
  EXPECT_EQ(mesh.NumFaces(), 1);
  EXPECT_FALSE(mesh.HasUVs());
  EXPECT_EQ(mesh.FUV.rows(), 0);
  ObjReadOptions options;
  options.require_uvs = true;
  EXPECT_THROW(ParseObj(text, "plain.obj", options), InputError);
}

// Random triangle meshes with UVs (some seams) through WriteObj and ReadObj.
TriMesh RandomMesh(std::mt19937* rng, int num_vertices, int num_faces) {
  std::uniform_real_distribution<double> coordinate(-150, 150);
  std::uniform_int_distribution<int> vertex(0, num_vertices - 1);
  TriMesh mesh;
  mesh.V.resize(num_vertices, 3);
  for (int i = 0; i < mesh.V.size(); ++i) mesh.V.data()[i] = coordinate(*rng);
  const int num_uvs = num_vertices + num_vertices / 3;
  mesh.UV.resize(num_uvs, 2);
  std::uniform_real_distribution<double> unit(0, 1);
  for (int i = 0; i < mesh.UV.size(); ++i) mesh.UV.data()[i] = unit(*rng);
  std::uniform_int_distribution<int> uv(0, num_uvs - 1);
  mesh.F.resize(num_faces, 3);
  mesh.FUV.resize(num_faces, 3);
  for (int f = 0; f < num_faces; ++f) {
    for (int i = 0; i < 3; ++i) {
      mesh.F(f, i) = vertex(*rng);
      mesh.FUV(f, i) = uv(*rng);
    }
  }
  return mesh;
}

TEST(ObjIo, WriteReadRoundTripToThePrecisionWritten) {
  TempDir dir;
  for (const unsigned seed : {1u, 7u, 23u}) {
    std::mt19937 rng(seed);
    const TriMesh mesh = RandomMesh(&rng, 50 + static_cast<int>(seed), 80);
    for (const int precision : {6, 9, 17}) {
      const fs::path path = dir.path() / fmt::format("m{}_{}.obj", seed, precision);
      WriteObj(path, mesh, precision);
      const TriMesh back = ReadObj(path);
      ASSERT_EQ(back.F, mesh.F);
      ASSERT_EQ(back.FUV, mesh.FUV);
      // `precision` significant digits: relative error below 10^(1-p).
      const double relative = std::pow(10.0, 1 - precision);
      for (int i = 0; i < mesh.V.size(); ++i) {
        EXPECT_NEAR(back.V.data()[i], mesh.V.data()[i],
                    relative * std::abs(mesh.V.data()[i]))
            << "seed " << seed << " precision " << precision;
      }
      for (int i = 0; i < mesh.UV.size(); ++i) {
        EXPECT_NEAR(back.UV.data()[i], mesh.UV.data()[i],
                    relative * std::abs(mesh.UV.data()[i]));
      }
      if (precision == 17) {
        EXPECT_EQ(back.V, mesh.V);
      }
    }
  }
}

TEST(ObjIo, WritesShapePositionsWithTheTopology) {
  TempDir dir;
  std::mt19937 rng(5);
  const TriMesh mesh = RandomMesh(&rng, 30, 40);
  const MatX3d shape = mesh.V.array() + 3.5;
  WriteObj(dir.path() / "shape.obj", mesh, shape, 17);
  const TriMesh back = ReadObj(dir.path() / "shape.obj");
  EXPECT_EQ(back.V, shape);
  EXPECT_EQ(back.F, mesh.F);
  EXPECT_EQ(back.UV, mesh.UV);
}

TEST(ObjIo, WriteRefusesNonFiniteAndLeavesNoFile) {
  TempDir dir;
  std::mt19937 rng(3);
  TriMesh mesh = RandomMesh(&rng, 10, 5);
  mesh.V(4, 1) = std::nan("");
  const fs::path path = dir.path() / "bad.obj";
  EXPECT_THROW(WriteObj(path, mesh), InputError);
  EXPECT_FALSE(fs::exists(path));
}

TEST(ObjIo, ReadObjOfAMissingFileNamesIt) {
  TempDir dir;
  try {
    ReadObj(dir.path() / "absent.obj");
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file().filename(), "absent.obj");
  }
}

// Every malformed file: the error names the file and the offending line.
struct BadObj {
  const char* what;
  std::string text;
  int line;  // expected line (0: whole file)
};

TEST(ObjIo, RefusesMalformedFilesNamingFileAndLine) {
  const std::string head = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n";
  const std::vector<BadObj> cases = {
      {"face cut off after a slash", head + "f 1/1 2/2 3/\n", 7},
      {"face cut off to two corners", head + "f 1/1 2/2\n", 7},
      {"vertex cut off", "v 0 0 0\nv 1 0\n", 2},
      {"vertex index out of range", head + "f 1/1 2/2 4/3\n", 7},
      {"uv index out of range", head + "f 1/1 2/2 3/9\n", 7},
      {"relative index out of range", head + "f 1/1 2/2 -4/3\n", 7},
      {"index zero", head + "f 0/1 2/2 3/3\n", 7},
      {"normal index out of range", head + "f 1/1/1 2/2/1 3/3/1\n", 7},
      {"NaN coordinate", "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n", 2},
      {"Inf coordinate", "v 0 0 0\nv 1 0 0\nv 0 inf 0\nf 1 2 3\n", 3},
      {"huge coordinate", "v 0 0 1e999\n", 1},
      {"NaN uv", head + "vt nan 0\n", 7},
      {"malformed number", "v 0 0 0\nv 1 0x 0\n", 2},
      {"malformed index", head + "f 1/1 2/a 3/3\n", 7},
      {"uvs on some corners only", head + "f 1/1 2 3/3\n", 7},
      {"uvs on some faces only", head + "f 1/1 2/2 3/3\nf 1 2 3\n", 8},
      {"unknown statement (truncated keyword)", head + "usemt skin\n", 7},
      {"empty file", "", 0},
      {"comments only", "# nothing\n\n", 0},
  };
  for (const BadObj& bad : cases) {
    SCOPED_TRACE(bad.what);
    try {
      ParseObj(bad.text, "dir/bad.obj");
      ADD_FAILURE() << "accepted: " << bad.what;
    } catch (const InputError& e) {
      EXPECT_EQ(e.file(), fs::path("dir/bad.obj"));
      EXPECT_EQ(e.line(), bad.line) << e.what();
      EXPECT_NE(std::string(e.what()).find("bad.obj"), std::string::npos);
    }
  }
}

}  // namespace
}  // namespace hmc
