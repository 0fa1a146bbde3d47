// `hmc experiment` as a user runs it on a small synthetic actor: the table
// has one row per material x noise x method, its numbers are those `hmc
// eval` gives on the written files, its meshes are those `hmc solve
// --method` gives on the written bundles, the pictures are written, and bad
// options fail with a clear message.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <string>

#include "core/file_util.h"
#include "core/mesh_sequence.h"
#include "tests/cli_runner.h"

namespace hmc {
namespace {

namespace fs = std::filesystem;

void ExpectClose(double got, double want, const std::string& what) {
  EXPECT_NEAR(got, want, 1e-9 * (1 + std::abs(want))) << what;
}

void ExpectSameStats(const nlohmann::json& got, const nlohmann::json& want,
                     const std::string& what) {
  EXPECT_EQ(got.at("count").get<int64_t>(), want.at("count").get<int64_t>())
      << what;
  for (const char* key : {"mean_mm", "rms_mm", "p95_mm", "max_mm"}) {
    ExpectClose(got.at(key).get<double>(), want.at(key).get<double>(),
                what + " " + key);
  }
}

class ExperimentCli : public ::testing::TestWithParam<int> {};

TEST_P(ExperimentCli, TableIsCompleteAndAgreesWithEvalAndSolve) {
  const int seed = GetParam();
  const fs::path dir = fs::temp_directory_path() /
                       fmt::format("hmc_experiment_test_{}_{}", getpid(), seed);
  fs::remove_all(dir);
  fs::create_directories(dir);
  const fs::path actor = dir / "actor", out = dir / "exp";
  CliResult r = RunHmc(
      fmt::format("-q actor synth --out '{}' --seed {} --grid_u 48 --grid_v 40 "
                  "--dataset_inbetweens false --dataset_combos false "
                  "--holdout 1",
                  actor.string(), seed),
      dir);
  ASSERT_EQ(r.exit_code, 0) << r.err;

  const std::vector<std::string> kinds = {"dataset", "combos", "performance",
                                          "heldout"};
  const std::vector<std::string> noises = {"0", "0.5"};
  const std::vector<std::string> methods = {
      "robust", "lgi", "blendshape", "blendshape-bounded", "interp", "lgi-rbf",
      "robust-global"};
  r = RunHmc(fmt::format("-q experiment --actor '{}' --out '{}' --seed {} "
                         "--kinds dataset,combos,performance,heldout "
                         "--noise_mm 0,0.5 "
                         "--frames combos:5,performance:6,heldout:4 "
                         "--write_meshes true --picture_frame 2 "
                         "--nn.uv_resolution 256",
                         actor.string(), out.string(), seed),
             dir);
  ASSERT_EQ(r.exit_code, 0) << r.err;

  const nlohmann::json results =
      nlohmann::json::parse(ReadFile(out / "results.json"));
  const std::string md = ReadFile(out / "results.md");
  const nlohmann::json& rows = results.at("rows");
  const int shapes = results.at("shapes").get<int>();
  ASSERT_EQ(rows.size(), kinds.size() * noises.size() * methods.size());
  std::map<std::string, nlohmann::json> by_key;
  for (const nlohmann::json& row : rows) {
    const std::string key = row.at("material").get<std::string>() + "/" +
                            row.at("method").get<std::string>();
    EXPECT_TRUE(by_key.emplace(key, row).second) << "duplicate " << key;
  }
  const std::map<std::string, int> frames = {
      {"dataset", shapes}, {"combos", 5}, {"performance", 6}, {"heldout", 4}};
  for (const std::string& kind : kinds) {
    for (const std::string& noise : noises) {
      const std::string material = kind + "_n" + noise;
      for (const std::string& method : methods) {
        const auto it = by_key.find(material + "/" + method);
        ASSERT_NE(it, by_key.end()) << material << " " << method;
        EXPECT_EQ(it->second.at("frames").get<int>(), frames.at(kind));
        EXPECT_EQ(it->second.at("bad_frames").get<int>(), 0);
        // The local data's share: robust's in [0, 1], none without them.
        if (method == "robust" || method == "robust-global") {
          const double share = it->second.at("local_share").get<double>();
          EXPECT_GE(share, 0.0) << material;
          EXPECT_LE(share, 1.0) << material;
          if (method == "robust-global") {
            EXPECT_EQ(share, 0.0) << material;
          }
        } else {
          EXPECT_FALSE(it->second.contains("local_share")) << material << method;
        }
        EXPECT_NE(md.find(fmt::format("| {} | {} | {} |", kind, noise, method)),
                  std::string::npos)
            << material << " " << method;
      }
    }
    EXPECT_TRUE(fs::exists(out / (kind + "_n0") / "bundles.csv"));
  }
  for (const std::string& method : methods) {
    EXPECT_TRUE(fs::exists(out / "images" /
                           fmt::format("combos_n0_frame000002_{}.png", method)))
        << method;
  }

  // The numbers are those of `hmc eval` on the written files.
  // (Every method on one material, one method on a second.)
  std::vector<std::pair<std::string, std::string>> checked;
  for (const std::string& method : methods) {
    checked.emplace_back("combos_n0.5", method);
  }
  checked.emplace_back("performance_n0", "lgi-rbf");
  for (const auto& [material, method] : checked) {
    {
      const fs::path m = out / material;
      r = RunHmc(fmt::format("-q eval --actor '{}' --truth '{}' --recon '{}' "
                             "--bundles '{}' --json",
                             actor.string(), (m / "truth.pc2").string(),
                             (m / (method + ".pc2")).string(),
                             (m / "bundles.csv").string()),
                 dir);
      ASSERT_EQ(r.exit_code, 0) << r.err;
      const nlohmann::json eval = nlohmann::json::parse(r.out).at("overall");
      const nlohmann::json& row = by_key.at(material + "/" + method);
      const std::string what = material + " " + method;
      ExpectSameStats(row.at("face"), eval.at("face"), what + " face");
      ExpectSameStats(row.at("all"), eval.at("all"), what + " all");
      ExpectSameStats(row.at("bundle"), eval.at("bundle"), what + " bundle");
      ExpectClose(row.at("detail_face_mm").get<double>(),
                  eval.at("detail_face_mm").get<double>(), what + " detail");
      ExpectClose(row.at("flicker_face_mm_per_frame2").get<double>(),
                  eval.at("flicker_face_mm_per_frame2").get<double>(),
                  what + " flicker");
      EXPECT_GT(row.at("face").at("mean_mm").get<double>(), 0.0) << what;
    }
  }

  // The meshes are those of `hmc solve --method` on the written bundles.
  for (const std::string method : {"blendshape", "interp"}) {
    const fs::path m = out / "combos_n0.5";
    const fs::path solved = dir / fmt::format("solve_{}.pc2", method);
    r = RunHmc(fmt::format("-q solve --method {} --actor '{}' --bundles '{}' "
                           "--jaw '{}' --out '{}'",
                           method, actor.string(), (m / "bundles.csv").string(),
                           (m / "jaw.csv").string(), solved.string()),
               dir);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const MeshSequence a = ReadMeshSequence(solved);
    const MeshSequence b = ReadMeshSequence(m / (method + ".pc2"));
    ASSERT_EQ(a.frames.size(), b.frames.size());
    for (size_t f = 0; f < a.frames.size(); ++f) {
      EXPECT_EQ((a.frames[f] - b.frames[f]).cwiseAbs().maxCoeff(), 0.0)
          << method << " frame " << f;
    }
  }
  fs::remove_all(dir);
}

INSTANTIATE_TEST_SUITE_P(Seeds, ExperimentCli, ::testing::Values(1, 2));

TEST(ExperimentCli, BadOptionsFailWithAClearMessage) {
  const fs::path dir =
      fs::temp_directory_path() / fmt::format("hmc_experiment_bad_{}", getpid());
  fs::remove_all(dir);
  fs::create_directories(dir);
  CliResult r = RunHmc(
      fmt::format("-q actor synth --out '{}' --grid_u 24 --grid_v 20 "
                  "--dataset_inbetweens false --dataset_combos false",
                  (dir / "actor").string()),
      dir);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = RunHmc(fmt::format("experiment --actor '{}' --out '{}' --methods lgi,rbf",
                         (dir / "actor").string(), (dir / "exp").string()),
             dir);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("item 'rbf' must be one of"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("lgi-rbf"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "exp" / "results.json"));
  r = RunHmc(fmt::format("solve --method spline --actor '{}' --bundles '{}' "
                         "--out '{}'",
                         (dir / "actor").string(),
                         (dir / "stdout.txt").string(),
                         (dir / "x.pc2").string()),
             dir);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("unknown solve method 'spline'"), std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("blendshape-bounded"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "x.pc2"));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace hmc
