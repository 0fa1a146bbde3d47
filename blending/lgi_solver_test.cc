#include "blending/lgi_solver.h"

#include <random>

#include <gtest/gtest.h>

#include "blending/thread_count_test_util.h"
#include "indexing/lgi_test_actor.h"

namespace hmc {
namespace {

// A stand-in for the natural-neighbour weights (blending/natural_neighbour.h
// is tested on its own): inverse squared UV distance to the 4 nearest sites,
// exactly 1 at a site; natural neighbours = 5 nearest sites, symmetrised.
// It has the properties the solver relies on (>= 0, sums to 1, 1 at a site).
NaturalNeighbourWeights StandInWeights(const Actor& actor,
                                       const ShapeData& data) {
  const MatX2d uv = PerVertexUVs(actor.neutral);
  const int V = actor.NumVertices(), K = data.num_bundles;
  std::vector<Vec2> site_uv(K);
  for (int k = 0; k < K; ++k) {
    site_uv[k] = Vec2::Zero();
    for (int i = 0; i < 3; ++i) {
      site_uv[k] += data.sites[k].bary[i] *
                    uv.row(actor.neutral.F(data.sites[k].face, i)).transpose();
    }
  }
  NaturalNeighbourWeights nn;
  std::vector<Eigen::Triplet<double>> triplets;
  nn.cell.resize(V);
  for (int v = 0; v < V; ++v) {
    std::vector<std::pair<double, int>> d;
    for (int k = 0; k < K; ++k) {
      d.emplace_back((uv.row(v).transpose() - site_uv[k]).squaredNorm(), k);
    }
    std::sort(d.begin(), d.end());
    nn.cell[v] = d[0].second;
    if (d[0].first < 1e-20) {
      triplets.emplace_back(v, d[0].second, 1.0);
      continue;
    }
    double total = 0;
    for (int i = 0; i < 4; ++i) total += 1 / d[i].first;
    for (int i = 0; i < 4; ++i) {
      triplets.emplace_back(v, d[i].second, 1 / d[i].first / total);
    }
  }
  nn.weights.resize(V, K);
  nn.weights.setFromTriplets(triplets.begin(), triplets.end());
  nn.site_neighbours.resize(K);
  for (int k = 0; k < K; ++k) {
    std::vector<std::pair<double, int>> d;
    for (int j = 0; j < K; ++j) {
      if (j != k) d.emplace_back((site_uv[j] - site_uv[k]).squaredNorm(), j);
    }
    std::sort(d.begin(), d.end());
    for (int i = 0; i < 5 && i < static_cast<int>(d.size()); ++i) {
      nn.site_neighbours[k].push_back(d[i].second);
      nn.site_neighbours[d[i].second].push_back(k);
    }
  }
  for (auto& list : nn.site_neighbours) {
    std::sort(list.begin(), list.end());
    list.erase(std::unique(list.begin(), list.end()), list.end());
  }
  return nn;
}

struct Fixture {
  explicit Fixture(testing::LgiTestActorOptions o,
                   SolveOptions solve_options = {})
      : actor(testing::MakeLgiTestActor(o)),
        data(ComputeShapeData(actor)),
        nn(StandInWeights(actor, data)) {
    std::vector<std::vector<int>> regions(data.num_bundles);
    for (int v = 0; v < nn.weights.rows(); ++v) {
      for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(
               nn.weights, v);
           it; ++it) {
        regions[it.col()].push_back(v);
      }
    }
    index = BuildShapeIndex(actor, data, regions, index_options);
    solver = std::make_unique<LgiSolver>(actor.neutral, data, index, nn,
                                         index_options, solve_options);
  }
  // The bundles of positions X (V x 3), every marker.
  BundleFrame Bundles(const MatX3d& X, int frame = 1) const {
    BundleFrame b;
    b.frame = frame;
    for (int k = 0; k < data.num_bundles; ++k) {
      b.bundles[data.bundle_names[k]] =
          EvaluateSurfacePoint(data.sites[k], actor.neutral.F, X);
    }
    return b;
  }

  Actor actor;
  ShapeData data;
  NaturalNeighbourWeights nn;
  IndexOptions index_options;
  ShapeIndex index;
  std::unique_ptr<LgiSolver> solver;
};

double MaxError(const MatX3d& a, const MatX3d& b) {
  return (a - b).rowwise().norm().maxCoeff();
}

// The paper's verification: bundles from each dataset shape reproduce it.
TEST(LgiSolver, VerificationReproducesEveryDatasetShape) {
  for (int seed = 1; seed <= 3; ++seed) {
    testing::LgiTestActorOptions o;
    o.seed = seed;
    Fixture fx(o);
    std::vector<BundleFrame> frames;
    std::vector<JawPose> jaw;
    for (int n = 0; n < fx.data.num_shapes; ++n) {
      frames.push_back(fx.Bundles(fx.actor.ShapePositions(n), n + 1));
      jaw.push_back(fx.actor.shapes[n].jaw);
    }
    const SolveResult r = fx.solver->SolveSequence(frames, jaw);
    double worst = 0;
    for (int n = 0; n < fx.data.num_shapes; ++n) {
      ASSERT_TRUE(r.frames[n].ok);
      worst = std::max(worst, MaxError(r.meshes[n], fx.actor.ShapePositions(n)));
    }
    EXPECT_LE(worst, 1e-3) << "seed " << seed;
    EXPECT_EQ(r.summary.bundles_projected, 0);
  }
}

// Random mixtures of dataset shapes under random jaw poses: the surface
// passes through every bundle that sits on a vertex and is inside its data;
// residuals of bundles inside triangles are reported.
TEST(LgiSolver, SurfacePassesThroughVertexBundles) {
  for (int seed = 1; seed <= 3; ++seed) {
    testing::LgiTestActorOptions o;
    o.seed = seed;
    Fixture fx(o);
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0, 1);
    int checked = 0;
    double worst_triangle = 0;
    for (int t = 0; t < 5; ++t) {
      // Unskinned mixture of three shapes, skinned with a random pose.
      MatX3d x = fx.actor.neutral.V;
      double w[3] = {u(rng), u(rng), u(rng)};
      const double total = w[0] + w[1] + w[2] + 0.2;
      for (int i = 0; i < 3; ++i) {
        const int n = static_cast<int>(u(rng) * fx.data.num_shapes) %
                      fx.data.num_shapes;
        for (int v = 0; v < x.rows(); ++v) {
          const float* d = fx.data.Displacement(v, n);
          for (int a = 0; d && a < 3; ++a) x(v, a) += w[i] / total * d[a];
        }
      }
      JawPose pose;
      pose.open_deg = 10 * u(rng);
      x = Skin(*fx.actor.jaw_rig, pose, x);
      FrameSolve f = fx.solver->SolveFrame(fx.Bundles(x), pose, nullptr);
      ASSERT_TRUE(f.ok);
      fx.solver->Blend(&f);
      for (int k = 0; k < fx.data.num_bundles; ++k) {
        const BundleSolve& b = f.bundles[k];
        if (b.status != BundleSolve::Status::kInside) continue;
        if (fx.actor.markers[k].vertex >= 0) {
          EXPECT_LE(b.residual, 1e-4) << "bundle " << k;
          ++checked;
        } else {
          worst_triangle = std::max(worst_triangle, b.residual);
        }
      }
    }
    EXPECT_GT(checked, 0);
    ::testing::Test::RecordProperty(
        "max_residual_in_triangles_mm_seed" + std::to_string(seed),
        std::to_string(worst_triangle));
    std::printf("seed %d: %d vertex bundles checked; bundles inside triangles: "
                "max residual %.4g mm\n", seed, checked, worst_triangle);
  }
}

// Bundle skinning matches per-vertex skinning of the neutral exactly (the
// surface point of the skinned neutral).
TEST(LgiSolver, BundleSkinningMatchesVertexSkinningOfTheNeutral) {
  const Actor actor = testing::MakeLgiTestActor({});
  const ShapeData data = ComputeShapeData(actor);
  JawPose pose;
  pose.open_deg = 17;
  pose.protrude_mm = 2;
  const MatX3d skinned = Skin(*actor.jaw_rig, pose, actor.neutral.V);
  for (int k = 0; k < data.num_bundles; ++k) {
    const Vec3 p = EvaluateSurfacePoint(data.sites[k], actor.neutral.F, skinned);
    EXPECT_LT((SkinBundle(data, k, pose, data.site_neutral.row(k).transpose()) - p)
                  .norm(), 1e-10);
  }
}

TEST(LgiSolver, JawUnskinThenSkinIsIdentity) {
  const Actor actor = testing::MakeLgiTestActor({});
  const ShapeData data = ComputeShapeData(actor);
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int t = 0; t < 50; ++t) {
    JawPose pose;
    pose.open_deg = 20 * u(rng);
    pose.lateral_deg = 5 * u(rng);
    pose.protrude_mm = 3 * u(rng);
    const int k = t % data.num_bundles;
    const Vec3 p(50 * u(rng), 50 * u(rng), 50 * u(rng));
    const Vec3 back = SkinBundle(data, k, pose, UnskinBundle(data, k, pose, p));
    EXPECT_LT((back - p).norm(), 1e-10);
    // And per vertex: Skin(Unskin(X)) == X.
    const MatX3d x = actor.ShapePositions(t % data.num_shapes);
    EXPECT_LT(MaxError(Skin(*actor.jaw_rig, pose, Unskin(*actor.jaw_rig, pose, x)), x),
              1e-10);
  }
}

// Bundles of the neutral under a pure jaw pose not in the dataset: the
// neutral is a cloud point of every bundle, so the result is the skinned
// neutral with no linearisation error.
TEST(LgiSolver, PureJawRotationIsExact) {
  for (int seed = 1; seed <= 3; ++seed) {
    testing::LgiTestActorOptions o;
    o.seed = seed;
    Fixture fx(o);
    JawPose pose;
    pose.open_deg = 12.5 + seed;
    pose.lateral_deg = 2.0;
    pose.protrude_mm = 1.5;
    const MatX3d truth = Skin(*fx.actor.jaw_rig, pose, fx.actor.neutral.V);
    const SolveResult r =
        fx.solver->SolveSequence({fx.Bundles(truth)}, {pose});
    EXPECT_LE(MaxError(r.meshes[0], truth), 1e-6);
  }
}

// A bundle pushed outside its data lands on the closest point of the union
// of simplices (brute force), here seen at a bundle on a vertex.
TEST(LgiSolver, OutsideBundleLandsOnClosestPoint) {
  testing::LgiTestActorOptions o;
  o.jaw = false;
  SolveOptions so;
  so.outside_slack_mm = 0.0;
  Fixture fx(o, so);
  int k = 0;
  while (fx.actor.markers[k].vertex < 0) ++k;
  BundleFrame frame = fx.Bundles(fx.actor.ShapePositions(0));
  const Vec3 pushed = frame.bundles[fx.data.bundle_names[k]] + Vec3(0, 0, 40);
  frame.bundles[fx.data.bundle_names[k]] = pushed;
  FrameSolve f = fx.solver->SolveFrame(frame, JawPose(), nullptr);
  const MatX3d x = fx.solver->Blend(&f);
  ASSERT_EQ(f.bundles[k].status, BundleSolve::Status::kProjected);
  const BundleIndex& b = fx.index.bundles[k];
  double best = 1e300;
  for (int s = 0; s < static_cast<int>(b.simplices().size()); ++s) {
    best = std::min(best, ClosestPointOnSimplex(b.Corners(s), pushed, 0).distance);
  }
  EXPECT_NEAR(f.bundles[k].distance, best, 1e-9);
  // The surface at the bundle is the closest point: at distance `best`.
  EXPECT_NEAR((x.row(fx.actor.markers[k].vertex).transpose() - pushed).norm(),
              best, 1e-5);
}

// An animated bundle that two candidates explain equally well (its
// neighbours sit half-way between the two candidates' predictions, with a
// tiny alternating jitter): without the temporal preference the choice
// flickers, with it the choice holds.
TEST(LgiSolver, EquallyValidCandidatesDoNotFlicker) {
  int tested = 0;
  for (int seed = 1; seed <= 4 && tested < 2; ++seed) {
    testing::LgiTestActorOptions o;
    o.seed = seed;
    o.jaw = false;
    Fixture fx(o);
    // Find a bundle and a position with two candidates that use different
    // shapes: the centroid of a tetrahedron, inside others too.
    for (int k = 0; k < fx.data.num_bundles && tested < 2; ++k) {
      const BundleIndex& b = fx.index.bundles[k];
      const auto& nbrs = fx.nn.site_neighbours[k];
      bool done = false;
      for (int s = 0; s < static_cast<int>(b.simplices().size()) && !done; ++s) {
        const SimplexCorners c = b.Corners(s);
        if (c.size != 4) continue;
        const Vec3 p = 0.25 * (c.x[0] + c.x[1] + c.x[2] + c.x[3]);
        const IndexQuery q = b.Query(p, 0.0, fx.index_options);
        if (q.candidates.size() < 2) continue;
        const IndexCandidate& A = q.candidates.front();
        const IndexCandidate& B = q.candidates.back();
        // Each frame: the neighbours half-way between A's and B's
        // predictions, shifted alternately towards A and towards B.
        std::vector<BundleFrame> frames;
        for (int t = 0; t < 8; ++t) {
          BundleFrame f = fx.Bundles(fx.actor.neutral.V, t + 1);
          f.bundles[fx.data.bundle_names[k]] = p;
          for (int j : nbrs) {
            const Vec3 pa = fx.solver->Predict(k, A, j);
            const Vec3 pb = fx.solver->Predict(k, B, j);
            const double mix = t % 2 == 0 ? 0.49 : 0.51;
            f.bundles[fx.data.bundle_names[j]] = (1 - mix) * pa + mix * pb;
          }
          frames.push_back(f);
        }
        auto choices = [&](double preference) {
          SolveOptions so;
          so.temporal_preference = preference;
          LgiSolver solver(fx.actor.neutral, fx.data, fx.index, fx.nn,
                           fx.index_options, so);
          std::vector<int> chosen;
          const SolveResult r = solver.SolveSequence(frames, {});
          for (const auto& fr : r.frames) chosen.push_back(fr.bundles[k].simplex);
          return chosen;
        };
        const std::vector<int> off = choices(0.0);
        std::set<int> distinct_off(off.begin(), off.end());
        if (distinct_off.size() < 2) continue;  // the jitter did not matter
        const std::vector<int> on = choices(0.25);
        std::set<int> distinct_on(on.begin(), on.end());
        EXPECT_EQ(distinct_on.size(), 1u) << "bundle " << k;
        ++tested;
        done = true;
      }
    }
  }
  EXPECT_GE(tested, 1);
}

TEST(LgiSolver, BitIdenticalForAnyThreadCount) {
  testing::LgiTestActorOptions o;
  o.seed = 2;
  Fixture fx(o);
  std::vector<BundleFrame> frames;
  std::vector<JawPose> jaw;
  for (int n = 0; n < fx.data.num_shapes; ++n) {
    MatX3d x = 0.5 * (fx.actor.ShapePositions(n) +
                      fx.actor.ShapePositions((n + 3) % fx.data.num_shapes));
    frames.push_back(fx.Bundles(x, n + 1));
    jaw.push_back(fx.actor.shapes[n].jaw);
  }
  ExpectSameMeshesForAnyThreadCount(
      [&] { return fx.solver->SolveSequence(frames, jaw); });
}

// A missing bundle is filled from its neighbours and flagged; a frame with
// too few bundles is flagged and repeats the previous good mesh.
TEST(LgiSolver, MissingBundlesAndBadFrames) {
  Fixture fx({});
  const MatX3d shape = fx.actor.ShapePositions(0);
  BundleFrame partial = fx.Bundles(shape, 1);
  partial.bundles.erase(fx.data.bundle_names[5]);
  partial.bundles["not_a_marker"] = Vec3(0, 0, 0);
  BundleFrame sparse;
  sparse.frame = 2;
  sparse.bundles[fx.data.bundle_names[0]] = Vec3(0, 0, 0);
  const SolveResult r = fx.solver->SolveSequence(
      {partial, sparse}, {fx.actor.shapes[0].jaw, JawPose()});
  ASSERT_TRUE(r.frames[0].ok);
  EXPECT_EQ(r.frames[0].bundles[5].status, BundleSolve::Status::kFilled);
  EXPECT_FALSE(r.frames[0].bundles[5].weights.empty());
  EXPECT_EQ(r.frames[0].unknown_markers, 1);
  EXPECT_FALSE(r.frames[1].ok);
  EXPECT_FALSE(r.frames[1].reason.empty());
  EXPECT_TRUE(r.meshes[1] == r.meshes[0]);
  EXPECT_EQ(r.summary.bad_frames, 1);
  EXPECT_EQ(r.summary.bundles_filled, 1);
}

// Smoothing constant weights changes nothing; smoothing alternating weights
// averages them.
TEST(LgiSolver, SmoothingAveragesWeightsOverTheWindow) {
  std::vector<FrameSolve> frames(5);
  for (int f = 0; f < 5; ++f) {
    frames[f].ok = true;
    frames[f].bundles.resize(2);
    frames[f].bundles[0].weights = {{3, 0.5}};
    frames[f].bundles[1].weights = {{f % 2, 1.0}};
  }
  LgiSolver::SmoothWeights(3, &frames);
  for (int f = 0; f < 5; ++f) {
    ASSERT_EQ(frames[f].bundles[0].weights.size(), 1u);
    EXPECT_DOUBLE_EQ(frames[f].bundles[0].weights[0].second, 0.5);
    double sum = 0;
    for (const auto& [n, w] : frames[f].bundles[1].weights) sum += w;
    EXPECT_NEAR(sum, 1.0, 1e-12);
  }
  // Frame 2 averages frames 1..3: shape 1, 0, 1.
  EXPECT_NEAR(frames[2].bundles[1].weights[0].second, 1.0 / 3, 1e-12);
  EXPECT_NEAR(frames[2].bundles[1].weights[1].second, 2.0 / 3, 1e-12);
}

}  // namespace
}  // namespace hmc

namespace hmc {
namespace {

// A shape that moves only the skin between the bundles (zero at every
// bundle's triangle) ties with the neutral wherever the bundles sit still:
// bundles of the neutral must give the neutral (least motion), and the other
// dataset shapes must still verify.
TEST(LgiSolver, InvisibleShapeDoesNotWinTies) {
  for (int seed = 1; seed <= 2; ++seed) {
    testing::LgiTestActorOptions o;
    o.seed = seed;
    o.jaw = false;
    Actor base = testing::MakeLgiTestActor(o);
    const int V = base.NumVertices();
    std::vector<char> at_site(V, 0);
    for (const Marker& m : base.markers) {
      for (int i = 0; i < 3; ++i) at_site[base.neutral.F(m.point.face, i)] = 1;
    }
    // Zero on and next to every site's triangle, 1 mm elsewhere.
    Shape ghost;
    ghost.name = "ghost";
    ghost.displacement = MatX3d::Zero(V, 3);
    for (int v = 0; v < V; ++v) {
      bool near = false;
      for (const Marker& m : base.markers) {
        const int c = base.neutral.F(m.point.face, 0);
        near |= (base.neutral.V.row(v) - base.neutral.V.row(c)).norm() < 12;
      }
      if (!near) ghost.displacement(v, 2) = 1.0;
    }
    base.shapes.push_back(ghost);
    const Actor& actor = base;
    const ShapeData data = ComputeShapeData(actor);
    const NaturalNeighbourWeights nn = StandInWeights(actor, data);
    std::vector<std::vector<int>> regions(data.num_bundles);
    for (int v = 0; v < V; ++v) {
      for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(
               nn.weights, v);
           it; ++it) {
        regions[it.col()].push_back(v);
      }
    }
    IndexOptions io;
    const ShapeIndex index = BuildShapeIndex(actor, data, regions, io);
    const LgiSolver solver(actor.neutral, data, index, nn, io, SolveOptions());
    auto bundles = [&](const MatX3d& x) {
      BundleFrame b;
      for (int k = 0; k < data.num_bundles; ++k) {
        b.bundles[data.bundle_names[k]] =
            EvaluateSurfacePoint(data.sites[k], actor.neutral.F, x);
      }
      return b;
    };
    FrameSolve f = solver.SolveFrame(bundles(actor.neutral.V), JawPose(), nullptr);
    EXPECT_LE(MaxError(solver.Blend(&f), actor.neutral.V), 1e-9);
    for (int n = 0; n + 1 < data.num_shapes; ++n) {
      FrameSolve g = solver.SolveFrame(bundles(actor.ShapePositions(n)),
                                       JawPose(), nullptr);
      EXPECT_LE(MaxError(solver.Blend(&g), actor.ShapePositions(n)), 1e-3)
          << "seed " << seed << " shape " << n;
    }
  }
}

}  // namespace
}  // namespace hmc
