#include "core/actor.h"

#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <random>
#include <set>
#include <sstream>
#include <string>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "core/error.h"
#include "core/file_util.h"
#include "core/temp_dir.h"
#include "core/obj_io.h"
#include "core/parallel.h"

namespace hmc {
namespace {

namespace fs = std::filesystem;

fs::path FixtureDir() {
  const char* source = std::getenv("HMC_SOURCE_DIR");
  const fs::path root = source != nullptr ? fs::path(source) : fs::current_path();
  return root / "tests" / "fixtures" / "dcc_actor";
}

// A small actor: an n x n grid in the xy plane, bulged in z, with UVs and a
// seam down the middle column (those vertices have two UVs), random shapes,
// markers by vertex and by face, and a jaw rig with rotated axes.
Actor MakeTestActor(unsigned seed, int n = 20) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> unit(0, 1);
  std::normal_distribution<double> normal(0, 1);
  Actor actor;
  actor.name = fmt::format("grid actor {}", seed);
  const double spacing = 5.0;
  TriMesh& mesh = actor.neutral;
  mesh.V.resize(n * n, 3);
  const int seam = n / 2;
  // UVs: one per vertex, plus a second copy of the seam column.
  mesh.UV.resize(n * n + n, 2);
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const double x = (i - n / 2) * spacing, y = (j - n / 2) * spacing;
      mesh.V.row(j * n + i) << x, y, 80 - 0.01 * (x * x + y * y) + 0.1 * normal(rng);
      mesh.UV.row(j * n + i) << 0.45 * i / (n - 1), double(j) / (n - 1);
    }
    mesh.UV.row(n * n + j) << 0.55 + 0.45 * seam / (n - 1), double(j) / (n - 1);
  }
  const int num_faces = 2 * (n - 1) * (n - 1);
  mesh.F.resize(num_faces, 3);
  mesh.FUV.resize(num_faces, 3);
  int f = 0;
  for (int j = 0; j + 1 < n; ++j) {
    for (int i = 0; i + 1 < n; ++i) {
      const int a = j * n + i, b = a + 1, c = a + n + 1, d = a + n;
      // Right of the seam, the seam column uses its second UV.
      const auto uv = [&](int v) {
        return (i >= seam && v % n == seam) ? n * n + v / n : v;
      };
      mesh.F.row(f) << a, b, c;
      mesh.FUV.row(f++) << uv(a), uv(b), uv(c);
      mesh.F.row(f) << a, c, d;
      mesh.FUV.row(f++) << uv(a), uv(c), uv(d);
    }
  }

  JawRig rig;
  rig.pivot = Vec3(normal(rng), -30 + normal(rng), -70 + normal(rng));
  rig.axes = Eigen::AngleAxisd(0.2 * normal(rng), Vec3(normal(rng), normal(rng),
                                                       normal(rng)).normalized())
                 .toRotationMatrix();
  rig.weights.resize(n * n);
  for (int v = 0; v < n * n; ++v) {
    rig.weights[v] = v % 7 == 0 ? (v % 2 ? 1.0 : 0.0) : unit(rng);
  }
  actor.jaw_rig = rig;

  const int num_shapes = 4;
  for (int s = 0; s < num_shapes; ++s) {
    Shape shape;
    shape.name = fmt::format("shape_{}", s);
    shape.displacement.resize(n * n, 3);
    for (int i = 0; i < shape.displacement.size(); ++i) {
      shape.displacement.data()[i] = 3 * normal(rng);
    }
    shape.jaw.open_deg = s % 2 ? 15 * unit(rng) : 0;
    shape.jaw.lateral_deg = s == 3 ? -2 * unit(rng) : 0;
    shape.jaw.protrude_mm = s == 3 ? 1.5 : 0;
    if (s > 0) shape.tags = {"mouth"};
    if (s == 2) shape.tags.push_back("brow");
    actor.shapes.push_back(shape);
  }

  std::uniform_int_distribution<int> vertex(0, n * n - 1);
  std::uniform_int_distribution<int> face(0, num_faces - 1);
  for (int m = 0; m < 12; ++m) {
    Marker marker;
    marker.name = fmt::format("m{:02d}", m);
    if (m % 3 == 0) {
      // SurfacePointAtVertex: what a vertex marker loads as.
      marker.vertex = vertex(rng);
      marker.point = SurfacePointAtVertex(mesh.F, marker.vertex);
    } else {
      marker.point.face = face(rng);
      const Vec3 w(unit(rng), unit(rng), unit(rng));
      marker.point.bary = w / w.sum();
    }
    if (m < 4) marker.tags.push_back("stable");
    if (m % 4 == 1) marker.tags.push_back("jaw");
    if (m % 2 == 0) marker.tags.push_back("mouth");
    actor.markers.push_back(marker);
  }
  return actor;
}

void ExpectActorsEqual(const Actor& expected, const Actor& actual,
                       double tolerance_mm) {
  EXPECT_EQ(actual.name, expected.name);
  ASSERT_EQ(actual.NumVertices(), expected.NumVertices());
  EXPECT_LE((actual.neutral.V - expected.neutral.V).cwiseAbs().maxCoeff(),
            tolerance_mm);
  EXPECT_EQ(actual.neutral.F, expected.neutral.F);
  EXPECT_EQ(actual.neutral.FUV, expected.neutral.FUV);
  ASSERT_EQ(actual.neutral.UV.rows(), expected.neutral.UV.rows());
  EXPECT_LE((actual.neutral.UV - expected.neutral.UV).cwiseAbs().maxCoeff(),
            1e-8);
  ASSERT_EQ(actual.shapes.size(), expected.shapes.size());
  for (size_t s = 0; s < expected.shapes.size(); ++s) {
    const Shape& a = actual.shapes[s];
    const Shape& e = expected.shapes[s];
    EXPECT_EQ(a.name, e.name);
    EXPECT_EQ(a.tags, e.tags);
    EXPECT_EQ(a.jaw.ToArray(), e.jaw.ToArray());
    // Shapes are stored as positions: the displacement carries the error of
    // both the shape's and the neutral's coordinates.
    EXPECT_LE((a.displacement - e.displacement).cwiseAbs().maxCoeff(),
              2 * tolerance_mm)
        << a.name;
  }
  ASSERT_EQ(actual.markers.size(), expected.markers.size());
  for (size_t m = 0; m < expected.markers.size(); ++m) {
    const Marker& a = actual.markers[m];
    const Marker& e = expected.markers[m];
    EXPECT_EQ(a.name, e.name);
    EXPECT_EQ(a.tags, e.tags);
    EXPECT_EQ(a.vertex, e.vertex);
    EXPECT_EQ(a.point.face, e.point.face) << a.name;
    EXPECT_LE((a.point.bary - e.point.bary).cwiseAbs().maxCoeff(), 1e-12)
        << a.name;
  }
  ASSERT_EQ(actual.jaw_rig.has_value(), expected.jaw_rig.has_value());
  if (expected.jaw_rig) {
    EXPECT_LE((actual.jaw_rig->pivot - expected.jaw_rig->pivot).norm(), 1e-12);
    EXPECT_LE((actual.jaw_rig->axes - expected.jaw_rig->axes).cwiseAbs().maxCoeff(),
              1e-12);
    EXPECT_EQ(actual.jaw_rig->weights, expected.jaw_rig->weights);
  }
}

TEST(Actor, WriteLoadRoundTrip) {
  for (const unsigned seed : {1u, 2u, 99u}) {
    SCOPED_TRACE(seed);
    const Actor actor = MakeTestActor(seed);
    TempDir dir;
    WriteActor(actor, dir.path() / "pkg");
    const Actor loaded = LoadActor(dir.path() / "pkg");
    EXPECT_EQ(loaded.units, "mm");
    EXPECT_EQ(loaded.dir, dir.path() / "pkg");
    EXPECT_NE(loaded.content_hash, 0u);
    // 9 significant digits of coordinates below 200 mm.
    ExpectActorsEqual(actor, loaded, 200 * 1e-8);

    // Full precision: exact positions.
    WriteActor(actor, dir.path() / "exact", 17);
    ExpectActorsEqual(actor, LoadActor(dir.path() / "exact"), 1e-12);
  }
}

TEST(Actor, ShapeFilesAreFullObjsADccOpens) {
  const Actor actor = MakeTestActor(4, 8);
  TempDir dir;
  WriteActor(actor, dir.path());
  const TriMesh shape = ReadObj(dir.path() / "shapes" / "shape_2.obj");
  EXPECT_EQ(shape.F, actor.neutral.F);
  EXPECT_EQ(shape.FUV, actor.neutral.FUV);
  EXPECT_LE((shape.V - actor.ShapePositions(2)).cwiseAbs().maxCoeff(), 1e-5);
}

TEST(Actor, LoadIsDeterministicWhateverTheThreadCount) {
  const Actor actor = MakeTestActor(7, 12);
  TempDir dir;
  WriteActor(actor, dir.path());
  Actor one_thread;
  {
    ThreadLimit limit(1);
    one_thread = LoadActor(dir.path());
  }
  const Actor all_threads = LoadActor(dir.path());
  EXPECT_EQ(one_thread.content_hash, all_threads.content_hash);
  ExpectActorsEqual(one_thread, all_threads, 0.0);
}

void ReplaceInFile(const fs::path& path, const std::string& from,
                   const std::string& to) {
  std::string text = ReadFile(path);
  const size_t pos = text.find(from);
  ASSERT_NE(pos, std::string::npos) << from << " not in " << path;
  text.replace(pos, from.size(), to);
  WriteFileAtomic(path, text);
}

TEST(Actor, ContentHashFollowsEveryFile) {
  const Actor actor = MakeTestActor(11, 8);
  TempDir dir;
  WriteActor(actor, dir.path());
  const uint64_t original = LoadActor(dir.path()).content_hash;
  EXPECT_EQ(LoadActor(dir.path()).content_hash, original);
  // Change each file of the package in a way that still loads.
  const std::vector<std::pair<fs::path, std::pair<std::string, std::string>>>
      edits = {
          {"actor.yaml", {"units: mm", "units: mm  # edited"}},
          {"neutral.obj", {"# hmc OBJ", "# edited\n# hmc OBJ"}},
          {"markers.csv", {"m00,", "m00x,"}},
          {"jaw_weights.txt", {"\n", "\n# edited\n"}},
          {"shapes/shape_3.obj", {"\nvt ", "\n# edited\nvt "}},
      };
  std::vector<uint64_t> hashes = {original};
  for (const auto& [file, edit] : edits) {
    SCOPED_TRACE(file.string());
    TempDir copy;
    fs::copy(dir.path(), copy.path(), fs::copy_options::recursive);
    ReplaceInFile(copy.path() / file, edit.first, edit.second);
    const uint64_t hash = LoadActor(copy.path()).content_hash;
    for (const uint64_t other : hashes) EXPECT_NE(hash, other);
    hashes.push_back(hash);
  }
}

TEST(Actor, LoadsTheHandAssembledDccPackageInMillimetres) {
  const fs::path fixture = FixtureDir();
  const Actor actor = LoadActor(fixture);
  EXPECT_EQ(actor.name, "dcc_actor");
  EXPECT_EQ(actor.units, "cm");
  // The raw file, in centimetres: every position is 10x in the actor.
  const TriMesh raw = ReadObj(fixture / "neutral.obj");
  ASSERT_EQ(actor.NumVertices(), raw.NumVertices());
  EXPECT_LE((actor.neutral.V - 10 * raw.V).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_NEAR(actor.neutral.V(0, 0), -40.0, 1e-12);  // "v -4.000000 3 4.68"
  EXPECT_NEAR(actor.neutral.V(0, 2), 46.8, 1e-12);
  EXPECT_EQ(actor.neutral.F, raw.F);
  // 10 quads, a pentagon and 2 triangles: 10 * 2 + 3 + 2 triangles.
  EXPECT_EQ(actor.neutral.NumFaces(), 25);
  ASSERT_TRUE(actor.neutral.HasUVs());
  // The seam: some vertex is used with two different UVs.
  std::vector<std::set<int>> uvs_of_vertex(actor.NumVertices());
  for (int f = 0; f < actor.neutral.NumFaces(); ++f) {
    for (int i = 0; i < 3; ++i) {
      uvs_of_vertex[actor.neutral.F(f, i)].insert(actor.neutral.FUV(f, i));
    }
  }
  int seam_vertices = 0;
  for (const auto& uvs : uvs_of_vertex) seam_vertices += uvs.size() > 1;
  EXPECT_GT(seam_vertices, 0);
  EXPECT_GT(actor.neutral.UV.rows(), actor.NumVertices());

  // Shapes: displacement = 10 x (shape file - neutral file).
  ASSERT_EQ(actor.shapes.size(), 2u);
  for (const Shape& shape : actor.shapes) {
    const TriMesh shape_raw =
        ReadObj(fixture / "shapes" / (shape.name + ".obj"));
    EXPECT_LE((shape.displacement - 10 * (shape_raw.V - raw.V))
                  .cwiseAbs()
                  .maxCoeff(),
              1e-9)
        << shape.name;
    EXPECT_GT(shape.displacement.cwiseAbs().maxCoeff(), 1.0) << shape.name;
  }
  const int jaw_open = actor.FindShape("jaw_open");
  ASSERT_GE(jaw_open, 0);
  EXPECT_EQ(actor.shapes[jaw_open].jaw.open_deg, 12.0);
  EXPECT_EQ(actor.shapes[jaw_open].tags, (std::vector<std::string>{"mouth", "jaw"}));
  const int brow = actor.FindShape("brow_raise");
  ASSERT_GE(brow, 0);
  EXPECT_TRUE(actor.shapes[brow].jaw.IsZero());

  // Jaw rig: pivot converted to mm, weights read per vertex.
  ASSERT_TRUE(actor.jaw_rig.has_value());
  EXPECT_LE((actor.jaw_rig->pivot - Vec3(0, -10, -60)).norm(), 1e-12);
  EXPECT_LE((actor.jaw_rig->axes - Mat3::Identity()).norm(), 1e-12);
  ASSERT_EQ(actor.jaw_rig->weights.size(), actor.NumVertices());
  EXPECT_EQ(actor.jaw_rig->weights.minCoeff(), 0.0);
  EXPECT_EQ(actor.jaw_rig->weights.maxCoeff(), 1.0);

  // Markers: by vertex sit on the vertex; by face (triangle, quad and
  // pentagon of the OBJ, weights per corner) sit where the weights put them
  // on the raw polygon (planar polygons: exact).
  ASSERT_EQ(actor.markers.size(), 7u);
  const Marker& bridge = actor.markers[actor.FindMarker("nose_bridge")];
  EXPECT_EQ(bridge.vertex, 2);
  EXPECT_TRUE(bridge.HasTag("stable"));
  EXPECT_LE((EvaluateSurfacePoint(bridge.point, actor.neutral.F, actor.neutral.V) -
             actor.neutral.V.row(2).transpose())
                .norm(),
            1e-12);
  const Marker& brow_l = actor.markers[actor.FindMarker("brow_l")];
  EXPECT_EQ(brow_l.tags, (std::vector<std::string>{"stable", "brow", "eye_l"}));
  // Polygon corners as written in neutral.obj (0-based) and the weights of
  // markers.csv.
  struct FaceMarker {
    const char* name;
    std::vector<int> corners;
    std::vector<double> weights;
  };
  const std::vector<FaceMarker> face_markers = {
      {"cheek_r", {5, 6, 1, 20, 0}, {0.1, 0.2, 0.2, 0.3, 0.2}},
      {"lip_corner_l", {13, 14, 9, 8}, {0.4, 0.1, 0.1, 0.4}},
      {"mouth_c", {16, 17, 12, 11}, {0.25, 0.25, 0.25, 0.25}},
      {"chin", {18, 19, 14}, {0.2, 0.3, 0.5}},
  };
  for (const FaceMarker& expected : face_markers) {
    SCOPED_TRACE(expected.name);
    const int m = actor.FindMarker(expected.name);
    ASSERT_GE(m, 0);
    EXPECT_EQ(actor.markers[m].vertex, -1);
    Vec3 position = Vec3::Zero();
    for (size_t k = 0; k < expected.corners.size(); ++k) {
      position += expected.weights[k] * 10 * raw.V.row(expected.corners[k]).transpose();
    }
    const Vec3 loaded = EvaluateSurfacePoint(actor.markers[m].point,
                                             actor.neutral.F, actor.neutral.V);
    EXPECT_LE((loaded - position).norm(), 1e-9);
    EXPECT_GE(actor.markers[m].point.bary.minCoeff(), 0.0);
    EXPECT_NEAR(actor.markers[m].point.bary.sum(), 1.0, 1e-12);
  }
}

TEST(Actor, DccPackageSurvivesWriteAndLoad) {
  const Actor actor = LoadActor(FixtureDir());
  TempDir dir;
  WriteActor(actor, dir.path(), 17);
  const Actor back = LoadActor(dir.path());
  EXPECT_EQ(back.units, "mm");
  ExpectActorsEqual(actor, back, 1e-12);
}

// ---------------------------------------------------------------------------
// Bad packages: each is the DCC fixture with one thing broken.

int LineContaining(const fs::path& path, const std::string& text) {
  std::ifstream in(path);
  std::string line;
  for (int number = 1; std::getline(in, line); ++number) {
    if (line.find(text) != std::string::npos) return number;
  }
  ADD_FAILURE() << text << " not found in " << path;
  return -1;
}

struct BadPackage {
  const char* what;
  std::function<void(const fs::path&)> edit;
  fs::path file;            // relative to the package: the file to blame
  std::string line_marker;  // text on the blamed line ("" = no line)
};

void ExpectRefused(const BadPackage& bad) {
  SCOPED_TRACE(bad.what);
  TempDir dir;
  const fs::path package = dir.path() / "pkg";
  fs::copy(FixtureDir(), package, fs::copy_options::recursive);
  bad.edit(package);
  const int expected_line =
      bad.line_marker.empty() ? 0 : LineContaining(package / bad.file, bad.line_marker);
  try {
    LoadActor(package);
    ADD_FAILURE() << "accepted a package with " << bad.what;
  } catch (const InputError& e) {
    EXPECT_EQ(e.file().lexically_normal(), (package / bad.file).lexically_normal())
        << e.what();
    EXPECT_NE(std::string(e.what()).find(bad.file.filename().string()),
              std::string::npos)
        << e.what();
    if (expected_line > 0) {
      EXPECT_EQ(e.line(), expected_line) << e.what();
    }
  }
}

std::function<void(const fs::path&)> Replace(const fs::path& file,
                                             const std::string& from,
                                             const std::string& to) {
  return [=](const fs::path& package) { ReplaceInFile(package / file, from, to); };
}

TEST(Actor, RefusesTruncatedAndBrokenObjs) {
  const fs::path neutral = "neutral.obj";
  const fs::path jaw_open = "shapes/jaw_open.obj";
  const fs::path brow = "shapes/brow_raise.obj";
  ExpectRefused({"a face line cut off",
                 [](const fs::path& p) {
                   std::string text = ReadFile(p / "neutral.obj");
                   text.resize(text.rfind("15/22/15") + 3);  // "... 15/"
                   WriteFileAtomic(p / "neutral.obj", text);
                 },
                 neutral, "19/24/19 15/"});
  ExpectRefused({"a face index out of range",
                 Replace(jaw_open, "f 19/24/19 20/25/20 15/22/15",
                         "f 19/24/19 22/25/20 15/22/15"),
                 jaw_open, "22/25/20"});
  ExpectRefused({"a NaN coordinate in the neutral",
                 Replace(neutral, "v 2.000000 1.000000 4.920000",
                         "v 2.000000 nan 4.920000"),
                 neutral, "v 2.000000 nan"});
  ExpectRefused({"an Inf coordinate in a shape",
                 Replace(brow, "v 4.000000 -1.000000 4.680000",
                         "v 4.000000 -1.000000 inf"),
                 brow, "-1.000000 inf"});
  ExpectRefused({"a neutral without UVs",
                 [](const fs::path& p) {
                   std::string text = ReadFile(p / "neutral.obj");
                   std::string out;
                   std::istringstream in(text);
                   std::string line;
                   while (std::getline(in, line)) {
                     if (line.rfind("vt ", 0) == 0) continue;
                     if (line.rfind("f ", 0) == 0) {
                       // v/vt/vn -> v//vn
                       std::string face;
                       std::istringstream corners(line.substr(2));
                       std::string corner;
                       while (corners >> corner) {
                         const size_t a = corner.find('/');
                         const size_t b = corner.rfind('/');
                         face += " " + corner.substr(0, a) + "//" + corner.substr(b + 1);
                       }
                       line = "f" + face;
                     }
                     out += line + "\n";
                   }
                   WriteFileAtomic(p / "neutral.obj", out);
                 },
                 neutral, ""});
  ExpectRefused({"a shape with one vertex more than the neutral",
                 Replace(brow, "vt ", "v 1 2 3\nvt "), brow, ""});
  ExpectRefused({"a missing shape file",
                 [](const fs::path& p) { fs::remove(p / "shapes/brow_raise.obj"); },
                 brow, ""});
  ExpectRefused({"a missing neutral",
                 [](const fs::path& p) { fs::remove(p / "neutral.obj"); },
                 neutral, ""});
}

TEST(Actor, RefusesBadMarkers) {
  const fs::path csv = "markers.csv";
  ExpectRefused({"a vertex off the mesh",
                 Replace(csv, "brow_r,20,", "brow_r,21,"), csv, "brow_r,21,"});
  ExpectRefused({"a negative vertex", Replace(csv, "brow_r,20,", "brow_r,-1,"),
                 csv, "brow_r,-1,"});
  ExpectRefused({"a face off the mesh", Replace(csv, "chin,,11,", "chin,,13,"),
                 csv, "chin,,13,"});
  ExpectRefused({"a negative weight",
                 Replace(csv, "0.2 0.3 0.5", "-0.2 0.7 0.5"), csv, "chin"});
  ExpectRefused({"weights not summing to 1",
                 Replace(csv, "0.2 0.3 0.5", "0.2 0.3 0.4"), csv, "chin"});
  ExpectRefused({"too few weights for a quad",
                 Replace(csv, "0.4 0.1 0.1 0.4", "0.4 0.1 0.5"), csv,
                 "lip_corner_l"});
  ExpectRefused({"a NaN weight", Replace(csv, "0.2 0.3 0.5", "0.2 nan 0.5"),
                 csv, "chin"});
  ExpectRefused({"both vertex and face",
                 Replace(csv, "chin,,11,", "chin,3,11,"), csv, "chin"});
  ExpectRefused({"a duplicate marker name",
                 Replace(csv, "mouth_c,,9,", "lip_corner_l,,9,"), csv,
                 "lip_corner_l,,9,"});
  ExpectRefused({"a missing column",
                 Replace(csv, "name,vertex,face,weights,tags", "name,vertex,face,weights"),
                 csv, "name,vertex"});
  ExpectRefused({"a missing markers file",
                 [](const fs::path& p) { fs::remove(p / "markers.csv"); }, csv, ""});
}

TEST(Actor, RefusesBadYamlAndJawRig) {
  const fs::path yaml = "actor.yaml";
  const fs::path weights = "jaw_weights.txt";
  ExpectRefused({"bad units", Replace(yaml, "units: cm", "units: inch"), yaml,
                 "units: inch"});
  ExpectRefused({"an unknown top-level key",
                 Replace(yaml, "units: cm", "units: cm\ncolour: red"), yaml,
                 "colour: red"});
  ExpectRefused({"an unknown shape key",
                 Replace(yaml, "tags: [brow]", "tags: [brow]\n    weight: 1"), yaml,
                 "weight: 1"});
  ExpectRefused({"an unknown jaw pose key",
                 Replace(yaml, "protrude_mm: 0.0", "protrude: 0.0"), yaml,
                 "protrude: 0.0"});
  ExpectRefused({"a duplicate shape name",
                 Replace(yaml, "name: brow_raise", "name: jaw_open"), yaml,
                 "name: jaw_open        #"});
  ExpectRefused({"a NaN pivot", Replace(yaml, "[0.0, -1.0, -6.0]", "[0.0, .nan, -6.0]"),
                 yaml, "pivot:"});
  ExpectRefused({"an Inf jaw pose", Replace(yaml, "open_deg: 12.0", "open_deg: .inf"),
                 yaml, "open_deg: .inf"});
  ExpectRefused({"non-orthonormal jaw axes",
                 Replace(yaml, "hinge: [1, 0, 0]", "hinge: [1, 0.1, 0]"), yaml,
                 "pivot:"});
  ExpectRefused({"left-handed jaw axes",
                 Replace(yaml, "forward: [0, 0, 1]", "forward: [0, 0, -1]"), yaml,
                 "pivot:"});
  ExpectRefused({"a missing required key",
                 Replace(yaml, "markers: markers.csv", ""), yaml, ""});
  ExpectRefused({"not YAML", Replace(yaml, "shapes:", "shapes: [\n"), yaml, ""});
  ExpectRefused({"a jaw weight above 1", Replace(weights, "\n1\n", "\n1.5\n"),
                 weights, "1.5"});
  ExpectRefused({"a negative jaw weight", Replace(weights, "\n0.5\n", "\n-0.5\n"),
                 weights, "-0.5"});
  ExpectRefused({"a NaN jaw weight", Replace(weights, "\n0.5\n", "\nnan\n"),
                 weights, "nan"});
  ExpectRefused({"one jaw weight missing", Replace(weights, "\n0.5\n", "\n"),
                 weights, ""});
  ExpectRefused({"a missing actor.yaml",
                 [](const fs::path& p) { fs::remove(p / "actor.yaml"); }, yaml, ""});
  ExpectRefused({"a jaw pose without a jaw rig",
                 [](const fs::path& p) {
                   std::string text = ReadFile(p / "actor.yaml");
                   const size_t begin = text.find("jaw_rig:");
                   const size_t end = text.find("shapes:");
                   text.erase(begin, end - begin);
                   WriteFileAtomic(p / "actor.yaml", text);
                 },
                 yaml, "- name: jaw_open"});
}

TEST(Actor, ValidateRefusesBadInMemoryActors) {
  const Actor good = MakeTestActor(3, 6);
  EXPECT_NO_THROW(ValidateActor(good, "memory"));
  const std::vector<std::pair<const char*, std::function<void(Actor*)>>> breaks = {
      {"no UVs", [](Actor* a) { a->neutral.UV.resize(0, 2); a->neutral.FUV.resize(0, 3); }},
      {"NaN vertex", [](Actor* a) { a->neutral.V(3, 1) = std::nan(""); }},
      {"short shape", [](Actor* a) { a->shapes[1].displacement.conservativeResize(5, 3); }},
      {"duplicate shape", [](Actor* a) { a->shapes[2].name = a->shapes[0].name; }},
      {"duplicate marker", [](Actor* a) { a->markers[2].name = a->markers[1].name; }},
      {"marker off the mesh", [](Actor* a) { a->markers[1].point.face = a->neutral.NumFaces(); }},
      {"negative bary", [](Actor* a) { a->markers[1].point.bary = Vec3(-0.5, 1, 0.5); }},
      {"weight above 1", [](Actor* a) { a->jaw_rig->weights[0] = 1.01; }},
      {"bad units", [](Actor* a) { a->units = "in"; }},
      {"bad shape name", [](Actor* a) { a->shapes[0].name = "../evil"; }},
  };
  for (const auto& [what, edit] : breaks) {
    Actor actor = good;
    edit(&actor);
    try {
      ValidateActor(actor, "memory");
      ADD_FAILURE() << "accepted " << what;
    } catch (const InputError& e) {
      EXPECT_EQ(e.file(), fs::path("memory")) << what;
    }
  }
  // WriteActor validates first and writes nothing for a bad actor.
  Actor bad = good;
  bad.markers[0].point.face = -1;
  TempDir dir;
  EXPECT_THROW(WriteActor(bad, dir.path() / "pkg"), InputError);
  EXPECT_FALSE(fs::exists(dir.path() / "pkg" / "actor.yaml"));
}

}  // namespace
}  // namespace hmc
