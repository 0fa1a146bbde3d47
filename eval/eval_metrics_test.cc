#include "eval/eval_metrics.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "core/error.h"
#include "indexing/lgi_test_actor.h"

namespace hmc {
namespace {

// Nearest-rank statistics by brute force.
ErrorStats Brute(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  ErrorStats s;
  s.count = static_cast<int64_t>(v.size());
  for (double x : v) {
    s.mean += x;
    s.rms += x * x;
  }
  s.mean /= v.size();
  s.rms = std::sqrt(s.rms / v.size());
  size_t rank = 1;
  while (static_cast<double>(rank) < 0.95 * v.size()) ++rank;
  s.p95 = v[rank - 1];
  s.max = v.back();
  return s;
}

void ExpectStats(const ErrorStats& got, const ErrorStats& want,
                 const char* what) {
  EXPECT_EQ(got.count, want.count) << what;
  EXPECT_NEAR(got.mean, want.mean, 1e-9) << what;
  EXPECT_NEAR(got.rms, want.rms, 1e-9) << what;
  EXPECT_NEAR(got.p95, want.p95, 1e-9) << what;
  EXPECT_NEAR(got.max, want.max, 1e-9) << what;
}

class EvalMetricsSeeds : public ::testing::TestWithParam<int> {};

// recon = truth + a random rigid translation c_f per frame, truth = random
// dataset mixtures: every vertex's error is |c_f|, the detail error is zero
// (translations have no Laplacian), flicker is mean |c_{f+1} - 2c_f +
// c_{f-1}|, and the bundle residual against the truth is |c_f|.
TEST_P(EvalMetricsSeeds, TranslatedSequenceAgainstClosedForms) {
  testing::LgiTestActorOptions ao;
  ao.seed = GetParam();
  const Actor actor = testing::MakeLgiTestActor(ao);
  std::mt19937 rng(GetParam());
  std::uniform_real_distribution<double> u(-1.0, 1.0), s(0.0, 1.0);
  const int F = 7, V = actor.NumVertices();
  std::vector<MatX3d> truth, recon;
  std::vector<Vec3> offsets;
  std::vector<int> numbers;
  for (int f = 0; f < F; ++f) {
    const int n = static_cast<int>(actor.shapes.size());
    truth.push_back(actor.neutral.V +
                    s(rng) * actor.shapes[f % n].displacement);
    offsets.emplace_back(u(rng), u(rng), u(rng));
    recon.push_back(truth.back().rowwise() + offsets.back().transpose());
    numbers.push_back(10 + f);
  }
  MeshMetricsOptions mo;
  mo.face_radius_mm = 15.0;
  const SequenceEvaluator evaluator(actor, mo);
  const SequenceMetrics m = evaluator.Evaluate(truth, recon, numbers, nullptr);
  int face = 0;
  for (uint8_t x : evaluator.face_mask()) face += x;
  ASSERT_GT(face, 0);
  ASSERT_LT(face, V);
  EXPECT_EQ(m.face_vertices, face);
  std::vector<double> all, face_pool, bundle;
  for (int f = 0; f < F; ++f) {
    const double e = offsets[f].norm();
    all.insert(all.end(), V, e);
    face_pool.insert(face_pool.end(), face, e);
    bundle.insert(bundle.end(), actor.markers.size(), e);
    EXPECT_EQ(m.per_frame[f].frame, numbers[f]);
    EXPECT_NEAR(m.per_frame[f].all.mean, e, 1e-9);
    EXPECT_NEAR(m.per_frame[f].bundle.max, e, 1e-9);
    EXPECT_LT(m.per_frame[f].detail_all, 1e-9);
  }
  ExpectStats(m.all, Brute(all), "all");
  ExpectStats(m.face, Brute(face_pool), "face");
  ExpectStats(m.bundle, Brute(bundle), "bundle");
  EXPECT_LT(m.detail_face, 1e-9);
  EXPECT_LT(m.detail_all, 1e-9);
  double flicker = 0;
  for (int f = 1; f + 1 < F; ++f) {
    flicker += (offsets[f + 1] - 2 * offsets[f] + offsets[f - 1]).norm();
  }
  flicker /= F - 2;
  EXPECT_EQ(m.flicker_all.frames_used, F - 2);
  EXPECT_NEAR(m.flicker_all.mean, flicker, 1e-9);
  EXPECT_NEAR(m.flicker_face.mean, flicker, 1e-9);
  for (int v = 0; v < V; v += 37) {
    double mean = 0;
    for (int f = 0; f < F; ++f) mean += offsets[f].norm() / F;
    EXPECT_NEAR(m.mean_vertex_error[v], mean, 1e-9);
  }
}

// Bundle residuals against given bundles: matched by frame number and
// marker name, missing markers skipped.
TEST_P(EvalMetricsSeeds, BundleResidualAgainstGivenBundles) {
  testing::LgiTestActorOptions ao;
  ao.seed = GetParam();
  const Actor actor = testing::MakeLgiTestActor(ao);
  std::mt19937 rng(50 + GetParam());
  std::normal_distribution<double> noise(0.0, 0.3);
  const std::vector<MatX3d> truth = {actor.neutral.V, actor.neutral.V};
  std::vector<BundleFrame> bundles(2);
  std::vector<double> expected;
  for (int f = 0; f < 2; ++f) {
    bundles[f].frame = 5 + f;
    for (size_t k = 0; k < actor.markers.size(); ++k) {
      if (static_cast<int>(k % 3) == f) continue;  // some markers missing
      const Marker& m = actor.markers[k];
      const Vec3 d(noise(rng), noise(rng), noise(rng));
      bundles[f].bundles[m.name] =
          EvaluateSurfacePoint(m.point, actor.neutral.F, actor.neutral.V) + d;
      expected.push_back(d.norm());
    }
  }
  const SequenceEvaluator evaluator(actor, MeshMetricsOptions());
  const SequenceMetrics m = evaluator.Evaluate(truth, truth, {5, 6}, &bundles);
  ExpectStats(m.bundle, Brute(expected), "bundle");
  EXPECT_EQ(m.all.max, 0.0);
  EXPECT_EQ(m.flicker_all.frames_used, 0);
}

TEST(EvalMetrics, MismatchedSizesAreInputErrors) {
  const Actor actor = testing::MakeLgiTestActor({});
  const SequenceEvaluator evaluator(actor, MeshMetricsOptions());
  const std::vector<MatX3d> one = {actor.neutral.V};
  const std::vector<MatX3d> wrong = {actor.neutral.V.topRows(5)};
  EXPECT_THROW(evaluator.Evaluate(one, wrong, {1}, nullptr), InputError);
  EXPECT_THROW(evaluator.Evaluate(one, one, {1, 2}, nullptr), InputError);
}

INSTANTIATE_TEST_SUITE_P(Seeds, EvalMetricsSeeds, ::testing::Values(1, 2, 3));

}  // namespace
}  // namespace hmc
