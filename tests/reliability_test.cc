// Hostile inputs to `hmc solve`, `hmc index` and `hmc actor check` as a user
// meets them (issue 24; docs/reliability.md): each gives a clear error or a
// flagged frame, never a silent wrong output, and never costs an earlier
// output.
#include <algorithm>
#include <random>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "core/calibration.h"
#include "core/file_util.h"
#include "core/frame_data.h"
#include "core/mesh_sequence.h"
#include "synth/footage.h"
#include "core/mesh.h"
#include "core/options.h"
#include "tests/cli_runner.h"
#include "tests/small_actor.h"

namespace hmc {
namespace {

namespace fs = std::filesystem;

const char* kCommon = "--nn.uv_resolution 256";

// One frame per dataset shape with Gaussian noise (sigma_mm), and its jaw.
struct Material {
  std::vector<BundleFrame> frames;
  std::vector<JawFrame> jaw;
};
Material MakeMaterial(const Actor& actor, int seed, double sigma_mm) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, sigma_mm);
  Material m;
  for (size_t n = 0; n < actor.shapes.size(); ++n) {
    BundleFrame f;
    f.frame = static_cast<int>(n) + 1;
    const MatX3d x = actor.ShapePositions(static_cast<int>(n));
    for (const Marker& marker : actor.markers) {
      f.bundles[marker.name] = EvaluateSurfacePoint(marker.point, actor.neutral.F, x) +
                               Vec3(noise(rng), noise(rng), noise(rng));
    }
    m.frames.push_back(f);
    m.jaw.push_back({f.frame, actor.shapes[n].jaw});
  }
  return m;
}

struct Fixture {
  fs::path dir;
  Actor actor;
  Material material;
};
Fixture MakeFixture(const std::string& name, int seed) {
  Fixture f;
  f.dir = FreshTestDir(name, seed);
  f.actor = WriteSmallActor(f.dir, seed, 24, 20);
  f.material = MakeMaterial(f.actor, seed, 0.05);
  WriteBundlesCsv(f.dir / "bundles.csv", f.material.frames);
  WriteJawCsv(f.dir / "jaw.csv", f.material.jaw);
  return f;
}

CliResult Solve(const Fixture& f, const fs::path& bundles, const fs::path& jaw,
                const fs::path& out, const std::string& extra = "") {
  return RunHmc(fmt::format("solve --actor '{}' --bundles '{}' --jaw '{}' --out '{}' {} {}",
                            (f.dir / "actor").string(), bundles.string(), jaw.string(),
                            out.string(), kCommon, extra),
                f.dir);
}

int Count(const std::string& text, const std::string& what) {
  int n = 0;
  for (size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

class ReliabilityCli : public ::testing::TestWithParam<int> {};

// Item 1: one stray frame number is an input error decided before any
// allocation (not a 576 MB output or bad_alloc); a small gap still solves.
TEST_P(ReliabilityCli, StrayFrameNumberIsAnErrorBeforeAllocation) {
  const Fixture f = MakeFixture("hmc_rel_gap", GetParam());
  for (const int stray : {100000, 2000000000, -2000000000}) {
    std::vector<BundleFrame> frames = f.material.frames;
    BundleFrame extra = frames.front();
    extra.frame = stray;
    frames.push_back(extra);
    std::sort(frames.begin(), frames.end(),
              [](const BundleFrame& a, const BundleFrame& b) { return a.frame < b.frame; });
    WriteBundlesCsv(f.dir / "stray.csv", frames);
    const CliResult r = Solve(f, f.dir / "stray.csv", f.dir / "jaw.csv", f.dir / "stray.pc2");
    EXPECT_EQ(r.exit_code, 2) << stray << ": " << r.err;
    EXPECT_NE(r.err.find("input.max_frame_gap"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(f.dir / "stray.pc2"));
  }
  // A gap within the option: the output spans it, the missing frames bad.
  std::vector<BundleFrame> frames = f.material.frames;
  const int last = frames.back().frame;
  frames.back().frame = last + 5;
  std::vector<JawFrame> jaw = f.material.jaw;
  jaw.back().frame = last + 5;
  WriteBundlesCsv(f.dir / "gap.csv", frames);
  WriteJawCsv(f.dir / "gap_jaw.csv", jaw);
  const CliResult ok = Solve(f, f.dir / "gap.csv", f.dir / "gap_jaw.csv", f.dir / "gap.pc2",
                             "--diagnostics '" + (f.dir / "gap.json").string() + "'");
  ASSERT_EQ(ok.exit_code, 0) << ok.err;
  EXPECT_EQ(ReadMeshSequence(f.dir / "gap.pc2").frames.size(), f.material.frames.size() + 5);
  const CliResult tight =
      Solve(f, f.dir / "gap.csv", f.dir / "gap_jaw.csv", f.dir / "gap2.pc2", "--input.max_frame_gap 3");
  EXPECT_EQ(tight.exit_code, 2) << tight.err;
  fs::remove_all(f.dir);
}

// Item 2: an outlier bundle is flagged, dropped from its frame and kept out
// of the noise estimate: the output is exactly the solve without that row.
// Absurd coordinates, and a plausible one: the true bundle moved 40 mm (a
// wrong name or a bad triangulation, still inside the face's box), which
// the solve would otherwise follow; no true bundle (material with noise) is
// dropped.
TEST_P(ReliabilityCli, OutlierBundleIsFlaggedAndTreatedAsMissing) {
  const Fixture f = MakeFixture("hmc_rel_outlier", GetParam());
  std::mt19937 rng(GetParam());
  const int frame = 1 + static_cast<int>(rng() % f.material.frames.size());
  const std::string marker =
      f.actor.markers[rng() % f.actor.markers.size()].name;
  const Vec3 truth = f.material.frames[frame - 1].bundles.at(marker);
  std::normal_distribution<double> normal;
  const Vec3 direction = Vec3(normal(rng), normal(rng), normal(rng)).normalized();
  for (const Vec3& value : {Vec3(1e4, -1e4, 1e4), Vec3(1e38, -1e38, 1e38),
                            Vec3(1e300, -1e300, 1e300), Vec3(truth + 40.0 * direction)}) {
    std::vector<BundleFrame> with = f.material.frames, without = f.material.frames;
    with[frame - 1].bundles[marker] = value;
    without[frame - 1].bundles.erase(marker);
    WriteBundlesCsv(f.dir / "with.csv", with);
    WriteBundlesCsv(f.dir / "without.csv", without);
    const CliResult a = Solve(f, f.dir / "with.csv", f.dir / "jaw.csv", f.dir / "a" / "with.pc2",
                              "--diagnostics '" + (f.dir / "a" / "d.json").string() + "'");
    ASSERT_EQ(a.exit_code, 0) << a.err;
    EXPECT_EQ(Count(a.err, "beyond their marker's reach"), 1) << a.err;
    const CliResult b = Solve(f, f.dir / "without.csv", f.dir / "jaw.csv", f.dir / "b" / "without.pc2");
    ASSERT_EQ(b.exit_code, 0) << b.err;
    EXPECT_EQ(ReadFile(f.dir / "a" / "with.pc2"), ReadFile(f.dir / "b" / "without.pc2"))
        << value.transpose();
    const nlohmann::json d = nlohmann::json::parse(ReadFile(f.dir / "a" / "d.json"));
    EXPECT_EQ(d["summary"]["outlier_bundles"].get<int>(), 1);
    for (const auto& fr : d["frames"]) {
      const std::vector<std::string> outliers = fr["outlier_markers"];
      if (fr["frame"].get<int>() == frame) {
        EXPECT_EQ(outliers, std::vector<std::string>{marker});
      } else {
        EXPECT_TRUE(outliers.empty());
      }
    }
  }
  fs::remove_all(f.dir);
}

// Item 3: an out-of-range jaw pose flags its frame (which repeats the
// previous good mesh); a jaw.csv with only a header solves nothing: exit 2,
// nothing written.
TEST_P(ReliabilityCli, JawPoseOutOfRangeIsFlaggedAndHeaderOnlyJawFails) {
  const Fixture f = MakeFixture("hmc_rel_jaw", GetParam());
  const int frame = 2 + GetParam() % (static_cast<int>(f.material.jaw.size()) - 1);
  for (const int column : {0, 1, 2}) {
    std::vector<JawFrame> jaw = f.material.jaw;
    std::array<double, 3> values = jaw[frame - 1].pose.ToArray();
    values[column] = column == 0 ? 1e300 : -1e3;
    jaw[frame - 1].pose = JawPose::FromArray(values);
    WriteJawCsv(f.dir / "bad_jaw.csv", jaw);
    const fs::path json = f.dir / "d.json";
    const CliResult r = Solve(f, f.dir / "bundles.csv", f.dir / "bad_jaw.csv", f.dir / "j.pc2",
                              "--diagnostics '" + json.string() + "'");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const nlohmann::json d = nlohmann::json::parse(ReadFile(json));
    for (const auto& fr : d["frames"]) {
      const bool bad = fr["frame"].get<int>() == frame;
      EXPECT_EQ(fr["ok"].get<bool>(), !bad) << fr["reason"];
      if (bad) {
        EXPECT_NE(fr["reason"].get<std::string>().find("jaw pose out of range"),
                  std::string::npos);
      }
    }
    const MeshSequence seq = ReadMeshSequence(f.dir / "j.pc2");
    EXPECT_EQ(seq.frames[frame - 1], seq.frames[frame - 2]);
  }
  WriteFileAtomic(f.dir / "header_only.csv", "frame,open_deg,lateral_deg,protrude_mm\n");
  const CliResult none = Solve(f, f.dir / "bundles.csv", f.dir / "header_only.csv", f.dir / "n.pc2");
  EXPECT_EQ(none.exit_code, 2) << none.err;
  EXPECT_NE(none.err.find("no frame can be solved"), std::string::npos) << none.err;
  EXPECT_FALSE(fs::exists(f.dir / "n.pc2"));
  fs::remove_all(f.dir);
}

// Item 6: every output path is checked before the solve: a bad one fails
// fast and leaves the earlier outputs as they were; missing folders of any
// output flag are created.
TEST_P(ReliabilityCli, OutputPathsAreCheckedBeforeTheSolve) {
  const Fixture f = MakeFixture("hmc_rel_outputs", GetParam());
  const fs::path out = f.dir / "out" / "mesh.pc2";
  ASSERT_EQ(Solve(f, f.dir / "bundles.csv", f.dir / "jaw.csv", out).exit_code, 0);
  const std::string mesh = ReadFile(out);
  const std::string options = ReadFile(f.dir / "out" / "options_used.yaml");
  fs::create_directories(f.dir / "a_folder.json");
  const std::string bad_outputs[] = {
      "--diagnostics '" + (f.dir / "a_folder.json").string() + "'",
      "--topology '" + (f.dir / "a_folder.json").string() + "'",
  };
  for (const std::string& bad : bad_outputs) {
    // Other options than the first run, so a solve would change the files.
    const CliResult r =
        Solve(f, f.dir / "bundles.csv", f.dir / "jaw.csv", out, bad + " --method lgi");
    EXPECT_EQ(r.exit_code, 2) << bad << ": " << r.err;
    EXPECT_NE(r.err.find("is a folder"), std::string::npos) << r.err;
    EXPECT_EQ(ReadFile(out), mesh);
    EXPECT_EQ(ReadFile(f.dir / "out" / "options_used.yaml"), options);
  }
  const CliResult deep = Solve(f, f.dir / "bundles.csv", f.dir / "jaw.csv", out,
                               "--diagnostics '" + (f.dir / "x" / "y" / "d.json").string() +
                                   "' --topology '" + (f.dir / "t" / "n.obj").string() + "'");
  EXPECT_EQ(deep.exit_code, 0) << deep.err;
  EXPECT_TRUE(fs::exists(f.dir / "x" / "y" / "d.json"));
  EXPECT_TRUE(fs::exists(f.dir / "t" / "n.obj"));
  fs::remove_all(f.dir);
}

// Item 9: unknown marker names are warned about once, with names and count.
TEST_P(ReliabilityCli, UnknownMarkerNamesAreWarnedOnce) {
  const Fixture f = MakeFixture("hmc_rel_unknown", GetParam());
  std::vector<BundleFrame> frames = f.material.frames;
  for (BundleFrame& frame : frames) {
    frame.bundles["not_a_marker"] = frame.bundles.begin()->second;
  }
  frames.front().bundles["typo_chin"] = Vec3::Zero();
  WriteBundlesCsv(f.dir / "unknown.csv", frames);
  const CliResult r = Solve(f, f.dir / "unknown.csv", f.dir / "jaw.csv", f.dir / "u.pc2");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(Count(r.err, "the actor does not have"), 1) << r.err;
  EXPECT_NE(r.err.find(fmt::format("{} row(s) name 2 marker(s)", frames.size() + 1)),
            std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("not_a_marker, typo_chin"), std::string::npos) << r.err;
  fs::remove_all(f.dir);
}

// Item 10: a key given twice in a config is refused (yaml-cpp keeps the last).
TEST_P(ReliabilityCli, DuplicateConfigKeysAreRefused) {
  const Fixture f = MakeFixture("hmc_rel_yaml", GetParam());
  const std::string configs[] = {"method: robust\nmethod: lgi\n",
                                 "solve:\n  smooth_window: 1\n  smooth_window: 3\n"};
  for (const std::string& text : configs) {
    WriteFileAtomic(f.dir / "config.yaml", text);
    const CliResult r = Solve(f, f.dir / "bundles.csv", f.dir / "jaw.csv", f.dir / "c.pc2",
                              "--config '" + (f.dir / "config.yaml").string() + "'");
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_NE(r.err.find("given twice"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(f.dir / "c.pc2"));
  }
  fs::remove_all(f.dir);
}

// Item 7: `hmc actor check` refuses what a solve cannot use.
TEST_P(ReliabilityCli, ActorCheckRefusesWhatTheSolveCannotUse) {
  const Fixture f = MakeFixture("hmc_rel_check", GetParam());
  const fs::path actor = f.dir / "actor";
  ASSERT_EQ(RunHmc("actor check '" + actor.string() + "'", f.dir).exit_code, 0);
  const std::string markers = ReadFile(actor / "markers.csv");
  // Comments and the header, no marker.
  const size_t header = markers.find("name,vertex");
  ASSERT_NE(header, std::string::npos);
  WriteFileAtomic(actor / "markers.csv", markers.substr(0, markers.find('\n', header) + 1));
  const CliResult empty = RunHmc("actor check '" + actor.string() + "'", f.dir);
  EXPECT_EQ(empty.exit_code, 2) << empty.err;
  EXPECT_NE(empty.err.find("markers.csv"), std::string::npos) << empty.err;
  EXPECT_NE(empty.err.find("no markers"), std::string::npos) << empty.err;
  WriteFileAtomic(actor / "markers.csv", markers);
  // The neutral's first vertex at 1e300 mm.
  const fs::path neutral = actor / "neutral.obj";
  ASSERT_TRUE(fs::exists(neutral));
  const std::string obj = ReadFile(neutral);
  const size_t v = obj.find("\nv ") + 1;
  WriteFileAtomic(neutral, obj.substr(0, v) + "v 1e300" +
                               obj.substr(obj.find(' ', obj.find(' ', v) + 1)));
  const CliResult huge = RunHmc("actor check '" + actor.string() + "'", f.dir);
  EXPECT_EQ(huge.exit_code, 2) << huge.err;
  EXPECT_NE(huge.err.find("sane bound"), std::string::npos) << huge.err;
  fs::remove_all(f.dir);
}

// Item 11: `hmc index` gives the same bytes for every run and thread count.
TEST_P(ReliabilityCli, IndexFileIsByteIdenticalAcrossRunsAndThreads) {
  const Fixture f = MakeFixture("hmc_rel_index", GetParam());
  std::vector<std::string> files;
  for (const int threads : {1, 2, 1}) {
    const fs::path scratch = f.dir / fmt::format("run{}", files.size());
    fs::create_directories(scratch);
    const CliResult r = RunHmc(fmt::format("--threads {} index --actor '{}' {}", threads,
                                           (f.dir / "actor").string(), kCommon),
                               scratch);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    std::string bytes;
    for (const auto& entry : fs::recursive_directory_iterator(scratch / "xdg_cache")) {
      if (entry.path().filename() == "lgi_index.bin") bytes = ReadFile(entry.path());
    }
    ASSERT_FALSE(bytes.empty());
    files.push_back(bytes);
  }
  EXPECT_EQ(files[0], files[1]);
  EXPECT_EQ(files[0], files[2]);
  fs::remove_all(f.dir);
}

INSTANTIATE_TEST_SUITE_P(Seeds, ReliabilityCli, ::testing::Values(1, 2));

// Item 4: whatever the lens, the fisheye subdivision's work is bounded by
// the image: with k1 = 1e6 every edge bends by far more than any tolerance,
// but the triangles project far off the image and are not split (before:
// up to 4^10 triangles per face, 5.3 GB and bad_alloc in `hmc synth shot`).
TEST(ReliabilityRender, SubdivisionIsBoundedByTheImageForAnyLens) {
  FisheyeCamera camera;
  camera.width = 64;
  camera.height = 64;
  camera.fx = camera.fy = 50;
  camera.cx = camera.cy = 32;
  camera.k = {1e6, 0, 0, 0};
  MatX3d X(4, 3);
  X << -20, -20, 100, 20, -20, 100, 20, 20, 100, -20, 20, 100;
  MatX3i F(4, 3);
  F << 0, 1, 2, 0, 2, 3, 2, 1, 0, 3, 2, 0;  // both windings
  const FisheyeTriangles tris = SubdivideForFisheye(camera, X, F, 0.05);
  EXPECT_GT(tris.stats.input_triangles, 0);
  EXPECT_LE(tris.stats.output_triangles, 4096);  // before: ~4 x 4^10
}

// The file names under `dir`, relative, sorted.
std::vector<std::string> Listing(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    names.push_back(fs::relative(e.path(), dir).string());
  }
  std::sort(names.begin(), names.end());
  return names;
}

// Items 4 and 5: a non-physical lens is refused before any work; a shot
// folder is written whole (a re-run leaves nothing of the earlier one), a
// folder hmc did not write and one inside an actor package are refused.
TEST(ReliabilityShot, LensOptionsAreCheckedAndShotFoldersAreWrittenWhole) {
  const fs::path dir = FreshTestDir("hmc_rel_shot", 1);
  const fs::path actor = dir / "A";
  ASSERT_EQ(RunHmc(fmt::format("actor synth --out '{}' --grid_u 24 --grid_v 20 "
                               "--dataset_inbetweens false --dataset_combos false",
                               actor.string()),
                   dir)
                .exit_code,
            0);
  auto shot = [&](const fs::path& out, const std::string& extra) {
    return RunHmc(fmt::format("synth shot --actor '{}' --out '{}' --rig.width 160 --rig.height 128 "
                              "--rig.focal_px 88 --contact_frames 0 --video png {}",
                              actor.string(), out.string(), extra),
                  dir);
  };
  for (const std::string bad : {"--rig.k1 1e6", "--rig.k2 -50", "--rig.tag_size 1e9",
                                "--rig.upper_camera_y 1e300", "--threads -3"}) {
    const CliResult r = shot(dir / "bad", bad);
    EXPECT_EQ(r.exit_code, 2) << bad << ": " << r.err;
    EXPECT_NE((r.out + r.err).find("invalid option"), std::string::npos) << r.out << r.err;
    EXPECT_FALSE(fs::exists(dir / "bad")) << bad;
  }
  ASSERT_EQ(shot(dir / "fresh", "--frames 2").exit_code, 0);
  ASSERT_EQ(shot(dir / "shot", "--frames 4").exit_code, 0);
  EXPECT_TRUE(fs::exists(dir / "shot" / "cam0" / "frame_000004.png"));
  const CliResult again = shot(dir / "shot", "--frames 2");
  ASSERT_EQ(again.exit_code, 0) << again.err;
  EXPECT_EQ(Listing(dir / "shot"), Listing(dir / "fresh"));
  for (const auto& e : fs::directory_iterator(dir)) {
    EXPECT_EQ(e.path().filename().string().find(".tmp."), std::string::npos) << e.path();
  }
  // Not written by hmc synth shot: refused, left as it was.
  fs::create_directories(dir / "mine");
  WriteFileAtomic(dir / "mine" / "notes.txt", "keep me\n");
  const CliResult mine = shot(dir / "mine", "--frames 1");
  EXPECT_EQ(mine.exit_code, 2) << mine.err;
  EXPECT_EQ(Listing(dir / "mine"), std::vector<std::string>{"notes.txt"});
  const std::vector<std::string> package = Listing(actor);
  const CliResult inside = shot(actor / "shot", "--frames 1");
  EXPECT_EQ(inside.exit_code, 2) << inside.err;
  EXPECT_NE(inside.err.find("actor package"), std::string::npos) << inside.err;
  // Deeper: refused before any folder is created inside the package.
  const CliResult deep = shot(actor / "takes" / "shot", "--frames 1");
  EXPECT_EQ(deep.exit_code, 2) << deep.err;
  EXPECT_NE(deep.err.find("actor package"), std::string::npos) << deep.err;
  EXPECT_EQ(Listing(actor), package);
  fs::remove_all(dir);
}

// Items 5 and 6 for every command that writes: each output flag is checked
// before any input is read (the inputs here are not even valid), an output
// inside an actor package is refused, and a folder output that holds files
// hmc did not write is refused and left as it was.
TEST(ReliabilityOutputs, EveryCommandChecksItsOutputsFirst) {
  const fs::path dir = FreshTestDir("hmc_rel_outputs_all", 1);
  const fs::path package = dir / "A";
  fs::create_directories(package);
  WriteFileAtomic(package / "actor.yaml", "not read\n");
  WriteFileAtomic(dir / "file.txt", "a file, not a folder\n");
  fs::create_directories(dir / "mine");
  WriteFileAtomic(dir / "mine" / "notes.txt", "keep me\n");
  WriteFileAtomic(dir / "in.txt", "not an input of any command\n");
  const std::string in = (dir / "in.txt").string();
  WriteFileAtomic(dir / "in.pc2", "not a mesh sequence\n");
  const std::string a = package.string();
  // {command line with {} for the output path, the flag named, folder output}
  struct Case {
    std::string line;
    std::string flag;
    bool folder;
  };
  const std::vector<Case> cases = {
      {"track --shot " + in + " --calibration " + in + " --actor " + a + " --out {}", "--out", false},
      {"track --shot " + in + " --calibration " + in + " --actor " + a + " --out " +
           (dir / "t.csv").string() + " --diagnostics {}",
       "--diagnostics", false},
      {"track --shot " + in + " --calibration " + in + " --actor " + a + " --out " +
           (dir / "t.csv").string() + " --overlay {}",
       "--overlay", true},
      {"calibrate --shot " + in + " --calibration " + in + " --out {}", "--out", false},
      {"calibrate --shot " + in + " --calibration " + in + " --out " +
           (dir / "c.yaml").string() + " --report {}",
       "--report", false},
      {"triangulate --tracks " + in + " --calibration " + in + " --out {}", "--out", false},
      {"triangulate --tracks " + in + " --calibration " + in + " --out " +
           (dir / "b.csv").string() + " --rays {}",
       "--rays", false},
      {"stabilize --bundles " + in + " --actor " + a + " --out {}", "--out", true},
      {"jaw --bundles " + in + " --actor " + a + " --out {}", "--out", false},
      {"undistort --shot " + in + " --calibration " + in + " --out {}", "--out", true},
      {"solve --actor " + a + " --bundles " + in + " --out {}", "--out", false},
      {"eval --actor " + a + " --truth " + in + " --recon " + in + " --out {}", "--out", true},
      {"eval-tracks --tracks " + in + " --truth " + in + " --json {}", "--json", false},
      {"experiment --actor " + a + " --out {}", "--out", true},
      {"report --work " + in + " --shot " + in + " --actor " + a + " --out {}", "--out", true},
      {"run --shot " + in + " --actor " + a + " --calibration " + in + " --out {}", "--out", true},
      {"convert " + (dir / "in.pc2").string() + " {}", "OUT", false},
      {"actor preview " + a + " --out {}", "--out", false},
      {"debug voronoi --actor " + a + " --out {}", "--out", false},
  };
  const std::vector<std::string> listing = Listing(dir);
  for (const Case& c : cases) {
    const std::string name = c.folder ? "o" : "o.pc2";
    auto run = [&](const fs::path& out) {
      std::string line = c.line;
      line.replace(line.find("{}"), 2, "'" + out.string() + "'");
      return RunHmc(line, dir);
    };
    const CliResult inside = run(package / "sub" / name);
    EXPECT_EQ(inside.exit_code, 2) << c.line << ": " << inside.err;
    EXPECT_NE(inside.err.find(c.flag + ": refusing to write inside the actor package"),
              std::string::npos)
        << c.line << ": " << inside.err;
    const CliResult under_file = run(dir / "file.txt" / name);
    EXPECT_EQ(under_file.exit_code, 2) << c.line << ": " << under_file.err;
    EXPECT_NE(under_file.err.find(c.flag + ": cannot create its folder"), std::string::npos)
        << c.line << ": " << under_file.err;
    // solve and convert write a mesh sequence, which may be a folder.
    if (c.flag == "OUT" || c.line.rfind("solve", 0) == 0) continue;
    const CliResult wrong_kind = run(c.folder ? dir / "file.txt" : dir / "mine");
    EXPECT_EQ(wrong_kind.exit_code, 2) << c.line << ": " << wrong_kind.err;
    EXPECT_NE(wrong_kind.err.find(c.flag + (c.folder ? ": exists and is not a folder"
                                                     : ": is a folder, not a file")),
              std::string::npos)
        << c.line << ": " << wrong_kind.err;
  }
  // Folders written whole refuse one that holds files they did not write.
  const std::vector<std::string> whole = {
      "undistort --shot " + in + " --calibration " + in + " --out {}",
      "experiment --actor " + a + " --out {}",
      "report --work " + in + " --shot " + in + " --actor " + a + " --out {}",
      "track --shot " + in + " --calibration " + in + " --actor " + a + " --out " +
          (dir / "t.csv").string() + " --overlay {}"};
  for (const std::string& line : whole) {
    std::string l = line;
    l.replace(l.find("{}"), 2, "'" + (dir / "mine").string() + "'");
    const CliResult r = RunHmc(l, dir);
    EXPECT_EQ(r.exit_code, 2) << line << ": " << r.err;
    EXPECT_NE(r.err.find("refusing to replace a folder that is not empty"), std::string::npos)
        << line << ": " << r.err;
  }
  // Nothing was written anywhere (the runner's own stdout/stderr aside).
  auto without_runner_files = [](std::vector<std::string> names) {
    names.erase(std::remove_if(names.begin(), names.end(),
                               [](const std::string& n) {
                                 return n == "stdout.txt" || n == "stderr.txt" ||
                                        n.rfind("xdg_cache", 0) == 0;
                               }),
                names.end());
    return names;
  };
  const std::vector<std::string> after = without_runner_files(Listing(dir));
  const std::vector<std::string> before = without_runner_files(listing);
  EXPECT_EQ(after, before);
  fs::remove_all(dir);
}

// Issue 45, items 3, 6, 7, 10 and 11 (the ones decided before any input is
// read, so the inputs here need not be valid): hmc run refuses a folder
// holding files it did not write and leaves them; no command writes an
// output over an input or into an input folder; a path that is not UTF-8
// is refused up front; a calibration hmc run cannot use is named as the
// user's file.
TEST(ReliabilityStudio, WorkspacesAndOutputsNeverTakeUsersOrInputsFiles) {
  const fs::path dir = FreshTestDir("hmc_rel_studio", 1);
  const fs::path shot = dir / "S";
  fs::create_directories(shot / "cam0");
  WriteFileAtomic(shot / "calibration.yaml", "not read\n");
  const fs::path actor = dir / "A";
  fs::create_directories(actor);
  WriteFileAtomic(actor / "actor.yaml", "not read\n");
  auto run = [&](const fs::path& out, const fs::path& calibration) {
    return RunHmc(fmt::format("run --shot '{}' --actor '{}' --calibration '{}' --out '{}'",
                              shot.string(), actor.string(), calibration.string(), out.string()),
                  dir);
  };
  // Item 3: a user's notes and a client's report are not deleted.
  const fs::path d = dir / "D";
  fs::create_directories(d / "track");
  fs::create_directories(d / "report");
  WriteFileAtomic(d / "track" / "my_notes.txt", "notes\n");
  WriteFileAtomic(d / "report" / "final_client_report.pdf", "x\n");
  const CliResult users = run(d, shot / "calibration.yaml");
  EXPECT_EQ(users.exit_code, 2) << users.err;
  EXPECT_NE(users.err.find("did not write"), std::string::npos) << users.err;
  EXPECT_EQ(ReadFile(d / "track" / "my_notes.txt"), "notes\n");
  EXPECT_EQ(ReadFile(d / "report" / "final_client_report.pdf"), "x\n");
  // Item 6: the workspace in the shot, or in a camera folder of it.
  const std::vector<std::pair<fs::path, std::string>> inside = {
      {shot, "--out: is also the input --shot"},
      {shot / "cam0", "--out: lies inside the input folder --shot"},
      {shot / "work", "--out: lies inside the input folder --shot"}};
  for (const auto& [out, message] : inside) {
    const CliResult r = run(out, shot / "calibration.yaml");
    EXPECT_EQ(r.exit_code, 2) << out << ": " << r.err;
    EXPECT_NE(r.err.find(message), std::string::npos) << r.err;
  }
  EXPECT_FALSE(fs::exists(shot / "work"));
  // Item 7: an output that is an input, or lies in an input folder.
  const std::string cal = (shot / "calibration.yaml").string();
  const std::vector<std::pair<std::string, std::string>> overwrites = {
      {"calibrate --shot " + shot.string() + " --calibration " + cal + " --out " + cal,
       "--out: is also the input --calibration"},
      {"calibrate --shot " + shot.string() + " --calibration " + cal + " --out " +
           (shot / "refined.yaml").string(),
       "--out: lies inside the input folder --shot"},
      {"calibrate --shot " + shot.string() + " --calibration " + cal + " --out " +
           (dir / "c.yaml").string() + " --report " + cal,
       "--report: is also the input --calibration"},
      {"track --shot " + shot.string() + " --calibration " + cal + " --actor " + actor.string() +
           " --out " + (shot / "cam0" / "t.csv").string(),
       "--out: lies inside the input folder --shot"},
      {"triangulate --tracks " + cal + " --calibration " + cal + " --out " + cal,
       "--out: is also the input --tracks"},
      {"undistort --shot " + shot.string() + " --calibration " + cal + " --out " + dir.string(),
       "--out: holds the input --shot"},
      {"convert " + (dir / "m.pc2").string() + " " + (dir / "m.pc2").string(),
       "OUT: is also the input IN"},
  };
  for (const auto& [line, message] : overwrites) {
    const CliResult r = RunHmc(line, dir);
    EXPECT_EQ(r.exit_code, 2) << line << ": " << r.err;
    EXPECT_NE(r.err.find(message), std::string::npos) << line << ": " << r.err;
  }
  EXPECT_EQ(ReadFile(shot / "calibration.yaml"), "not read\n");
  EXPECT_FALSE(fs::exists(shot / "summary.json"));
  EXPECT_FALSE(fs::exists(shot / "options_used.yaml"));
  // Item 10: a workspace path that JSON cannot hold.
  const CliResult latin1 = run(dir / "W\xe9rk", shot / "calibration.yaml");
  EXPECT_EQ(latin1.exit_code, 2) << latin1.err;
  EXPECT_NE(latin1.err.find("not valid UTF-8"), std::string::npos) << latin1.err;
  EXPECT_FALSE(fs::exists(dir / "W\xe9rk"));
  // Item 11: a calibration of one camera is the user's file's fault.
  HelmetRig one;
  FisheyeCamera camera;
  camera.width = 64;
  camera.height = 48;
  camera.fx = camera.fy = 40;
  camera.cx = 32;
  camera.cy = 24;
  one.cameras.push_back({"cam0", camera, Rigid3::Identity()});
  WriteCalibration(dir / "one_camera.yaml", one);
  const CliResult lone = run(dir / "W", dir / "one_camera.yaml");
  EXPECT_EQ(lone.exit_code, 2) << lone.err;
  EXPECT_NE(lone.err.find((dir / "one_camera.yaml").string() + ": hmc run needs a rig of two cameras"),
            std::string::npos)
      << lone.err;
  fs::remove_all(dir);
}


// Issue 45, item 7 and "hmc run never overwrites a file it did not write":
// the side files a command names itself beside --out (summary.json,
// options_used.yaml, jaw_*.json/yaml, a default rays.csv) replace only a
// file of that name that hmc wrote. A user's file there is refused before
// any work, named, and left as it was; a rerun over the command's own
// side files, or over another command's, goes on.
TEST(ReliabilityStudio, SideFilesReplaceOnlyWhatHmcWrote) {
  const Fixture f = MakeFixture("hmc_rel_side_files", 1);
  const fs::path& dir = f.dir;
  const std::string in = (dir / "bundles.csv").string();
  const std::string a = (dir / "actor").string();
  // {command line with {} for the output folder, the side file, its mark}
  struct Case {
    std::string line;
    std::string side;
  };
  const std::vector<Case> cases = {
      {"track --shot " + in + " --calibration " + in + " --actor " + a + " --out {}/t.csv",
       "summary.json"},
      {"track --shot " + in + " --calibration " + in + " --actor " + a + " --out {}/t.csv",
       "options_used.yaml"},
      {"calibrate --shot " + in + " --calibration " + in + " --out {}/c.yaml", "summary.json"},
      {"calibrate --shot " + in + " --calibration " + in + " --out {}/c.yaml",
       "options_used.yaml"},
      {"triangulate --tracks " + in + " --calibration " + in + " --out {}/b.csv",
       "summary.json"},
      {"triangulate --tracks " + in + " --calibration " + in + " --out {}/b.csv",
       "options_used.yaml"},
      {"triangulate --tracks " + in + " --calibration " + in + " --out {}/b.csv", "rays.csv"},
      {"stabilize --bundles " + in + " --actor " + a + " --out {}", "summary.json"},
      {"stabilize --bundles " + in + " --actor " + a + " --out {}", "options_used.yaml"},
      {"jaw --bundles " + in + " --actor " + a + " --out {}/jaw.csv", "jaw_summary.json"},
      {"jaw --bundles " + in + " --actor " + a + " --out {}/jaw.csv", "jaw_options_used.yaml"},
      {"solve --actor " + a + " --bundles " + in + " --out {}/m.pc2", "options_used.yaml"},
  };
  // A user's files: notes, a JSON of another tool (its "stage" no hmc
  // command), a CSV with rays.csv's columns but not its header line.
  const std::vector<std::string> users = {
      "my notes\n", "{\"stage\": \"final\", \"client\": \"approved\"}\n",
      "frame, marker, camera, ox, oy, oz, dx, dy, dz\n"};
  int n = 0;
  for (const Case& c : cases) {
    for (const std::string& content : users) {
      const fs::path folder = dir / fmt::format("user{}", n++);
      fs::create_directories(folder);
      WriteFileAtomic(folder / c.side, content);
      std::string line = c.line;
      line.replace(line.find("{}"), 2, folder.string());
      const CliResult r = RunHmc(line, dir);
      EXPECT_EQ(r.exit_code, 2) << line << ": " << r.err;
      EXPECT_NE(r.err.find((folder / c.side).string() + ": " + c.side +
                           (c.line.rfind("stabilize", 0) == 0 ? " in --out" : " beside --out") +
                           ": a file hmc did not write"),
                std::string::npos)
          << line << ": " << r.err;
      EXPECT_EQ(ReadFile(folder / c.side), content) << line;
      EXPECT_EQ(Listing(folder), std::vector<std::string>{c.side}) << line;
    }
  }
  // Over its own side files and another command's, in one folder: twice.
  const fs::path out = dir / "out";
  for (int round = 0; round < 2; ++round) {
    const std::vector<std::string> lines = {
        fmt::format("stabilize --bundles '{}' --actor '{}' --out '{}'", in, a, out.string()),
        fmt::format("jaw --bundles '{}' --actor '{}' --out '{}'", (out / "bundles.csv").string(),
                    a, (out / "jaw.csv").string()),
        fmt::format("solve --actor '{}' --bundles '{}' --jaw '{}' --out '{}' {}", a,
                    (out / "bundles.csv").string(), (out / "jaw.csv").string(),
                    (out / "mesh.pc2").string(), kCommon)};
    for (const std::string& line : lines) {
      const CliResult r = RunHmc(line, dir);
      EXPECT_EQ(r.exit_code, 0) << round << ": " << line << ": " << r.err;
    }
  }
  // solve replaced the options_used.yaml of stabilize, and said so.
  EXPECT_EQ(ReadFile(out / "options_used.yaml").rfind(OptionsUsedMark("solve") + "\n", 0), 0u);
  EXPECT_EQ(nlohmann::json::parse(ReadFile(out / "summary.json"))["stage"], "stabilize");
  EXPECT_EQ(nlohmann::json::parse(ReadFile(out / "jaw_summary.json"))["stage"], "jaw");
  fs::remove_all(dir);
}

}  // namespace
}  // namespace hmc
