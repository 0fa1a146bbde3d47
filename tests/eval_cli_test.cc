// `hmc eval` as a user runs it: its numbers agree with an independent
// computation straight from the raw bytes of the PC2 files (header parsed
// here, not by core/mesh_sequence), its output files are written, and bad
// input fails with a message naming the file.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <vector>

#include "core/actor.h"
#include "core/file_util.h"
#include "tests/cli_runner.h"
#include "tests/small_actor.h"
#include "core/image_io.h"
#include "core/mesh_sequence.h"

namespace hmc {
namespace {

namespace fs = std::filesystem;

// A PC2 file parsed from its bytes (little endian): "POINTCACHE2\0",
// int32 version, int32 points, float start, float rate, int32 samples, then
// samples x points x 3 float32.
struct RawPc2 {
  int points = 0;
  int samples = 0;
  float start = 0;
  std::vector<float> data;
  double At(int f, int v, int c) const {
    return data[(static_cast<size_t>(f) * points + v) * 3 + c];
  }
};

RawPc2 ReadRawPc2(const fs::path& path) {
  const std::string bytes = ReadFile(path);
  RawPc2 pc;
  EXPECT_EQ(bytes.compare(0, 12, std::string("POINTCACHE2\0", 12)), 0);
  std::memcpy(&pc.points, bytes.data() + 16, 4);
  std::memcpy(&pc.start, bytes.data() + 20, 4);
  std::memcpy(&pc.samples, bytes.data() + 28, 4);
  pc.data.resize(static_cast<size_t>(pc.points) * pc.samples * 3);
  EXPECT_EQ(bytes.size(), 32 + pc.data.size() * 4);
  std::memcpy(pc.data.data(), bytes.data() + 32, pc.data.size() * 4);
  return pc;
}

struct Stats {
  double mean = 0, rms = 0, p95 = 0, max = 0;
};

Stats Brute(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  Stats s;
  for (double x : v) {
    s.mean += x;
    s.rms += x * x;
  }
  s.mean /= v.size();
  s.rms = std::sqrt(s.rms / v.size());
  s.max = v.back();
  size_t rank = 1;
  while (static_cast<double>(rank) < 0.95 * v.size()) ++rank;
  s.p95 = v[rank - 1];
  return s;
}

void ExpectStats(const nlohmann::json& j, const Stats& s, const char* what) {
  const double tol = 1e-9;
  EXPECT_NEAR(j["mean_mm"].get<double>(), s.mean, tol * (1 + s.mean)) << what;
  EXPECT_NEAR(j["rms_mm"].get<double>(), s.rms, tol * (1 + s.rms)) << what;
  EXPECT_NEAR(j["p95_mm"].get<double>(), s.p95, tol * (1 + s.p95)) << what;
  EXPECT_NEAR(j["max_mm"].get<double>(), s.max, tol * (1 + s.max)) << what;
}

class EvalCli : public ::testing::TestWithParam<int> {};

TEST_P(EvalCli, AgreesWithAnIndependentComputationFromThePc2Bytes) {
  const int seed = GetParam();
  const fs::path dir = FreshTestDir("hmc_eval_test", seed);
  const Actor actor = WriteSmallActor(dir, seed, 48, 40);
  const int V = actor.NumVertices();

  // Truth: a few dataset shapes; recon: the truth plus seeded noise and a
  // smooth offset, with one extra leading frame the truth does not have.
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0, 0.3);
  MeshSequence truth, recon;
  truth.start_frame = 5;
  recon.start_frame = 4;
  recon.frames.push_back(actor.neutral.V);
  for (int f = 0; f < 5; ++f) {
    const MatX3d t =
        actor.ShapePositions(f % static_cast<int>(actor.shapes.size()));
    MatX3d r = t;
    for (int v = 0; v < V; ++v) {
      for (int c = 0; c < 3; ++c) r(v, c) += noise(rng) * (f + 1) * 0.5;
      r(v, 1) += 0.2 * f * std::sin(t(v, 0) / 30.0);
    }
    truth.frames.push_back(t);
    recon.frames.push_back(r);
  }
  WriteMeshSequence(dir / "truth.pc2", truth);
  WriteMeshSequence(dir / "recon.pc2", recon);

  const CliResult r = RunHmc(
      fmt::format("eval --actor '{}' --truth '{}' --recon '{}' --out '{}' "
                  "--frames 6,9 --json --uv_resolution 64 --image_width 96 "
                  "--image_height 120",
                  (dir / "actor").string(), (dir / "truth.pc2").string(),
                  (dir / "recon.pc2").string(), (dir / "out").string()),
      dir);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json j = nlohmann::json::parse(r.out);

  // The independent computation.
  const RawPc2 rt = ReadRawPc2(dir / "truth.pc2");
  const RawPc2 rr = ReadRawPc2(dir / "recon.pc2");
  ASSERT_EQ(rt.points, V);
  const int offset = static_cast<int>(rt.start - rr.start);  // 1
  const double radius = j["face_region"]["radius_mm"].get<double>();
  std::vector<Vec3> marker_points;
  for (const Marker& m : actor.markers) {
    Vec3 x = Vec3::Zero();
    for (int i = 0; i < 3; ++i) {
      x += m.point.bary[i] *
           actor.neutral.V.row(actor.neutral.F(m.point.face, i)).transpose();
    }
    marker_points.push_back(x);
  }
  std::vector<char> face(V, 0);
  int face_count = 0;
  for (int v = 0; v < V; ++v) {
    for (const Vec3& p : marker_points) {
      if ((actor.neutral.V.row(v).transpose() - p).norm() <= radius) {
        face[v] = 1;
        ++face_count;
        break;
      }
    }
  }
  EXPECT_EQ(j["face_region"]["vertices"].get<int>(), face_count);
  EXPECT_GT(face_count, 0);
  EXPECT_LT(face_count, V);
  ASSERT_EQ(j["frames"].get<int>(), rt.samples);
  std::vector<double> all_pool, face_pool, bundle_pool;
  for (int f = 0; f < rt.samples; ++f) {
    std::vector<double> all, in_face, bundle;
    for (int v = 0; v < V; ++v) {
      double d2 = 0;
      for (int c = 0; c < 3; ++c) {
        const double d = rt.At(f, v, c) - rr.At(f + offset, v, c);
        d2 += d * d;
      }
      all.push_back(std::sqrt(d2));
      if (face[v]) in_face.push_back(std::sqrt(d2));
    }
    for (const Marker& m : actor.markers) {
      double d2 = 0;
      for (int c = 0; c < 3; ++c) {
        double d = 0;
        for (int i = 0; i < 3; ++i) {
          const int v = actor.neutral.F(m.point.face, i);
          d += m.point.bary[i] * (rr.At(f + offset, v, c) - rt.At(f, v, c));
        }
        d2 += d * d;
      }
      bundle.push_back(std::sqrt(d2));
    }
    const nlohmann::json& pf = j["per_frame"][f];
    EXPECT_EQ(pf["frame"].get<int>(), static_cast<int>(rt.start) + f);
    ExpectStats(pf["all"], Brute(all), "frame all");
    ExpectStats(pf["face"], Brute(in_face), "frame face");
    ExpectStats(pf["bundle"], Brute(bundle), "frame bundle");
    EXPECT_GT(pf["detail_all_mm"].get<double>(), 0.0);
    all_pool.insert(all_pool.end(), all.begin(), all.end());
    face_pool.insert(face_pool.end(), in_face.begin(), in_face.end());
    bundle_pool.insert(bundle_pool.end(), bundle.begin(), bundle.end());
  }
  ExpectStats(j["overall"]["all"], Brute(all_pool), "overall all");
  ExpectStats(j["overall"]["face"], Brute(face_pool), "overall face");
  ExpectStats(j["overall"]["bundle"], Brute(bundle_pool), "overall bundle");
  // More noise, more lost detail: the detail error grows over the frames.
  for (int f = 1; f < rt.samples; ++f) {
    EXPECT_GT(j["per_frame"][f]["detail_face_mm"].get<double>(),
              j["per_frame"][f - 1]["detail_face_mm"].get<double>());
  }

  // Output files.
  const fs::path out = dir / "out";
  EXPECT_TRUE(fs::exists(out / "eval.json"));
  EXPECT_TRUE(fs::exists(out / "options_used.yaml"));
  const std::string csv = ReadFile(out / "per_frame.csv");
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), rt.samples + 1);
  const cv::Mat uv = ReadExr(out / "error_uv_mean.exr");
  EXPECT_EQ(uv.rows, 64);
  EXPECT_EQ(uv.cols, 64);
  for (int frame : {6, 9}) {
    const cv::Mat png = ReadPng(out / fmt::format("frame_{:06d}.png", frame));
    EXPECT_GT(png.cols, 3 * 96);
    EXPECT_TRUE(fs::exists(out / fmt::format("error_uv_{:06d}.exr", frame)));
  }
  EXPECT_FALSE(fs::exists(out / "frame_000007.png"));
  // A re-run with other --frames replaces the folder whole: no picture of
  // the earlier run stays beside the new ones (issue 24, item 5).
  const CliResult rerun = RunHmc(
      fmt::format("eval --actor '{}' --truth '{}' --recon '{}' --out '{}' --frames 7 "
                  "--uv_resolution 64 --image_width 96 --image_height 120",
                  (dir / "actor").string(), (dir / "truth.pc2").string(),
                  (dir / "recon.pc2").string(), out.string()),
      dir);
  ASSERT_EQ(rerun.exit_code, 0) << rerun.err;
  EXPECT_TRUE(fs::exists(out / "frame_000007.png"));
  for (int frame : {6, 9}) {
    EXPECT_FALSE(fs::exists(out / fmt::format("frame_{:06d}.png", frame))) << frame;
    EXPECT_FALSE(fs::exists(out / fmt::format("error_uv_{:06d}.exr", frame))) << frame;
  }

  // Identical sequences: every error is zero.
  const CliResult same =
      RunHmc(fmt::format("eval --actor '{}' --truth '{}' --recon '{}' --json",
                         (dir / "actor").string(), (dir / "truth.pc2").string(),
                         (dir / "truth.pc2").string()),
             dir);
  ASSERT_EQ(same.exit_code, 0) << same.err;
  const nlohmann::json js = nlohmann::json::parse(same.out);
  EXPECT_EQ(js["overall"]["all"]["max_mm"].get<double>(), 0.0);
  EXPECT_EQ(js["overall"]["detail_all_mm"].get<double>(), 0.0);

  // The readable table.
  const CliResult table =
      RunHmc(fmt::format("eval --actor '{}' --truth '{}' --recon '{}'",
                         (dir / "actor").string(), (dir / "truth.pc2").string(),
                         (dir / "recon.pc2").string()),
             dir);
  ASSERT_EQ(table.exit_code, 0) << table.err;
  EXPECT_NE(table.out.find("face"), std::string::npos) << table.out;

  // A recon of another vertex count: an error naming the file.
  MeshSequence wrong;
  wrong.frames.push_back(MatX3d::Zero(V - 1, 3));
  WriteMeshSequence(dir / "wrong.pc2", wrong);
  const CliResult bad =
      RunHmc(fmt::format("eval --actor '{}' --truth '{}' --recon '{}'",
                         (dir / "actor").string(), (dir / "truth.pc2").string(),
                         (dir / "wrong.pc2").string()),
             dir);
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.err.find("wrong.pc2"), std::string::npos) << bad.err;
  fs::remove_all(dir);
}

INSTANTIATE_TEST_SUITE_P(Seeds, EvalCli, ::testing::Values(1, 4));

}  // namespace
}  // namespace hmc
