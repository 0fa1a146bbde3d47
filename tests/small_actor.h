// Fixtures of the CLI integration tests: a fresh temporary folder and a
// small synthetic actor package written into it (48 x 40 or 96 x 80 grids,
// no in-betweens or combinations, so a test stays within seconds).
#pragma once

#include <unistd.h>

#include <filesystem>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "core/actor.h"
#include "core/frame_data.h"
#include "core/mesh.h"
#include "synth/synth_actor.h"

namespace hmc {

// <tmp>/<name>_<pid>_<seed>, emptied.
inline std::filesystem::path FreshTestDir(const std::string& name, int seed) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() /
      fmt::format("{}_{}_{}", name, getpid(), seed);
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

// Synthesizes the actor of `seed` at grid_u x grid_v, writes it to
// dir/actor (17 significant digits) and returns it as loaded back.
inline Actor WriteSmallActor(const std::filesystem::path& dir, int seed,
                             int grid_u, int grid_v) {
  SynthActorOptions options;
  options.seed = seed;
  options.grid_u = grid_u;
  options.grid_v = grid_v;
  options.dataset_inbetweens = false;
  options.dataset_combos = false;
  WriteActor(SynthesizeActor(options), dir / "actor", 17);
  return LoadActor(dir / "actor");
}

// One frame per dataset shape (frame n + 1: shape n): every marker's
// exact position on the shape, and the shape's jaw pose.
inline void DatasetShapeFrames(const Actor& actor, std::vector<BundleFrame>* frames,
                               std::vector<JawFrame>* jaw) {
  for (size_t n = 0; n < actor.shapes.size(); ++n) {
    BundleFrame f;
    f.frame = static_cast<int>(n) + 1;
    const MatX3d x = actor.ShapePositions(static_cast<int>(n));
    for (const Marker& m : actor.markers) {
      f.bundles[m.name] = EvaluateSurfacePoint(m.point, actor.neutral.F, x);
    }
    frames->push_back(f);
    jaw->push_back({f.frame, actor.shapes[n].jaw});
  }
}

}  // namespace hmc
