// Test-only: a small synthetic actor with its real lgi model (index and
// natural-neighbour weights) and solver, shared by the tests of the solvers
// built on lgi (lgi-rbf, robust).
#pragma once

#include <random>

#include "blending/lgi_solver.h"
#include "blending/solve_index_cache.h"
#include "indexing/lgi_test_actor.h"

namespace hmc {

struct SmallLgiModel {
  SmallLgiModel(int seed, bool jaw)
      : actor(MakeActor(seed, jaw)),
        model(BuildLgiModel(actor, IndexOptions(), SmallNn())),
        lgi(actor.neutral, model.data, model.index, model.nn, IndexOptions(),
            SolveOptions()) {}

  static Actor MakeActor(int seed, bool jaw) {
    testing::LgiTestActorOptions o;
    o.seed = seed;
    o.jaw = jaw;
    return testing::MakeLgiTestActor(o);
  }
  static NaturalNeighbourOptions SmallNn() {
    NaturalNeighbourOptions nn;
    nn.uv_resolution = 256;
    return nn;
  }

  // The markers' surface points on `x` (V x 3), plus Gaussian noise of std
  // `noise` per coordinate (drawn from *rng when noise > 0), as one bundle
  // frame.
  BundleFrame Bundles(int frame, const MatX3d& x, double noise = 0.0,
                      std::mt19937* rng = nullptr) const {
    std::normal_distribution<double> n(0.0, noise > 0 ? noise : 1.0);
    BundleFrame b;
    b.frame = frame;
    for (const Marker& m : actor.markers) {
      Vec3 p = EvaluateSurfacePoint(m.point, actor.neutral.F, x);
      if (noise > 0) p += Vec3(n(*rng), n(*rng), n(*rng));
      b.bundles[m.name] = p;
    }
    return b;
  }

  Actor actor;
  LgiModel model;
  LgiSolver lgi;
};

}  // namespace hmc
