// Test material for stabilization/ (tests only: uses synth/): a small
// synthetic actor and a shot's exact ground truth without rendering --
// helmet-space and head-space bundles, head_from_helmet and the jaw pose per
// frame, from the same performance and slip `hmc synth shot` uses.
#pragma once

#include <memory>
#include <random>
#include <vector>

#include "core/actor.h"
#include "core/frame_data.h"
#include "stabilization/marker_model.h"
#include "stabilization/stabilize.h"
#include "synth/face_model.h"
#include "synth/performance.h"
#include "synth/synth_actor.h"
#include "synth/synth_random.h"

namespace hmc {

struct SmallActor {
  SynthActorOptions options;
  std::unique_ptr<FaceModel> model;
  Actor actor;
  MarkerModel markers;
};

// The synthetic actor of `options`.
inline SmallActor MakeTestActor(const SynthActorOptions& options) {
  SmallActor out;
  out.options = options;
  out.model = std::make_unique<FaceModel>(out.options);
  out.actor = SynthesizeActorFromModel(*out.model, out.options);
  out.markers = ComputeMarkerModel(out.actor);
  return out;
}

// The synthetic actor of `seed` on a 24 x 20 grid without in-betweens or
// combinations (a second or two to build).
inline SmallActor MakeSmallActor(int seed) {
  SynthActorOptions options;
  options.seed = seed;
  options.grid_u = 24;
  options.grid_v = 20;
  options.dataset_inbetweens = false;
  options.dataset_combos = false;
  return MakeTestActor(options);
}

struct ShotTruth {
  std::vector<BundleFrame> helmet;  // bundles_helmet.csv (+ noise)
  std::vector<BundleFrame> head;    // bundles.csv (no noise)
  std::vector<PoseFrame> head_from_helmet;
  std::vector<JawFrame> jaw;
};

// Evaluates `activations` (or the performance of `perf` when empty) with
// the slip of `perf`; Gaussian noise of noise_mm per helmet coordinate
// (seeded by perf.seed). Frames numbered from 1.
inline ShotTruth MakeShotTruth(const SmallActor& a, const PerformanceOptions& perf,
                               double noise_mm,
                               std::vector<Eigen::VectorXd> activations = {}) {
  const ShotPerformance performance = MakePerformance(*a.model, perf);
  if (activations.empty()) activations = performance.activations;
  SynthRandom noise = SynthRandom::Stream(static_cast<uint64_t>(perf.seed), 99);
  ShotTruth out;
  const MatX3i& F = a.actor.neutral.F;
  for (size_t f = 0; f < activations.size(); ++f) {
    const int frame = static_cast<int>(f) + 1;
    const MatX3d X = a.model->Evaluate(activations[f]);
    const Rigid3 head_from_helmet = performance.head_from_helmet[f];
    BundleFrame head{frame, {}}, helmet{frame, {}};
    for (const Marker& marker : a.actor.markers) {
      const Vec3 p = EvaluateSurfacePoint(marker.point, F, X);
      head.bundles[marker.name] = p;
      Vec3 h = head_from_helmet.inverse() * p;
      for (int i = 0; i < 3; ++i) h[i] += noise_mm * noise.Normal();
      helmet.bundles[marker.name] = h;
    }
    out.head.push_back(head);
    out.helmet.push_back(helmet);
    out.head_from_helmet.push_back({frame, head_from_helmet});
    out.jaw.push_back({frame, a.model->JawPoseOf(activations[f])});
  }
  return out;
}

// A random rigid motion: a rotation of up to max_deg about a random axis
// and a translation of up to max_mm per axis.
inline Rigid3 RandomRigid(std::mt19937& rng, double max_deg, double max_mm) {
  std::normal_distribution<double> normal;
  std::uniform_real_distribution<double> uniform(-1, 1);
  Rigid3 t = Rigid3::Identity();
  t.linear() = Eigen::AngleAxisd(max_deg * M_PI / 180 * uniform(rng),
                                 Vec3(normal(rng), normal(rng), normal(rng)).normalized())
                   .toRotationMatrix();
  t.translation() = max_mm * Vec3(uniform(rng), uniform(rng), uniform(rng));
  return t;
}

inline std::vector<PoseFrame> Poses(const std::vector<StabilizedFrame>& frames) {
  std::vector<PoseFrame> out;
  for (const StabilizedFrame& f : frames) out.push_back({f.frame, f.head_from_helmet});
  return out;
}

}  // namespace hmc
