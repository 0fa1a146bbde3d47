// The synthetic actor (DESIGN.md section 6): a procedural, UV-parameterised
// face, a painted-marker layout, a jaw rig, FACS-like action units with
// nonlinear fine detail, and a dataset of shapes built from them.
// Deterministic by seed.
#pragma once

#include <string>
#include <vector>

#include "core/actor.h"
#include "core/options.h"

namespace hmc {

struct SynthActorOptions {
  int seed = 1;  // random seed: face proportions, marker jitter, dataset
  // (The generator's other options -- resolution, number of markers, ... --
  // are declared here by synth/; see configs/actor_synth.yaml.)

  void Register(OptionFields* fields);
  bool Check() const;
};

// The whole synthetic actor as an in-memory package (mm, head space).
Actor SynthesizeActor(const SynthActorOptions& options);

}  // namespace hmc
