// The synthetic actor (docs/synthetic.md): a procedural, UV-parameterised
// face, a painted-marker layout, a jaw rig, FACS-like action units with
// nonlinear fine detail, and a dataset of shapes built from them.
// Deterministic by seed. How it is made: docs/synthetic.md.
#pragma once

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "core/actor.h"
#include "core/options.h"

namespace hmc {

class FaceModel;

struct SynthActorOptions {
  int seed = 1;  // random seed: face proportions, marker jitter, detail phases
  std::string name = "synth_actor";  // actor name in actor.yaml
  int grid_u = 256;  // vertex columns of the face grid (>= 24); 256 x 200 = 51200 vertices
  int grid_v = 200;  // vertex rows of the face grid (>= 20)
  double proportion_jitter = 0.04;  // relative spread of the seeded face proportions
  double detail_scale = 1.0;        // scales wrinkle / fold amplitudes
  double marker_jitter_mm = 0.8;    // std of the seeded marker placement jitter (mm)
  bool dataset_inbetweens = true;   // add 50% (and some 25/75%) in-between shapes
  bool dataset_combos = true;       // add the combination shapes
  int shapes = 0;  // dataset size: 0 = the standard plan; more extends it with seeded in-betweens, pairwise and triple combinations (docs/synthetic.md, "Larger datasets")
  std::string rig = "generator";  // "generator" (nonlinear detail, jaw rig), "linear" (extremes as fixed displacements, no jaw rig) or "broad" (linear, artist-style broad overlapping units; docs/synthetic.md)
  int holdout = 0;                  // action units held out of the dataset (drawn from the seed, never a jaw unit)
  std::string holdout_units;        // comma-separated unit names held out (overrides the draw; synth.yaml records the resolved list)

  void Register(OptionFields* fields);
  bool Check() const;
};

// One dataset shape: its name, tags and the activations that build it.
struct DatasetEntry {
  std::string name;                // "AU12_lip_corner_puller_L_100", "combo_smile"
  Eigen::VectorXd activations;     // K unit activations
  std::vector<std::string> tags;   // union of the units' region tags
};

// The held-out action units (indices into model.units(), ascending): test
// material the dataset never sees (docs/synthetic.md "Held-out units").
// If options.holdout_units names units, exactly those (jaw units allowed:
// the harder case, by explicit choice only); else `options.holdout` units
// drawn from the seed among the units that do not drive the jaw (a partial
// Fisher-Yates shuffle of the non-jaw units in catalog order, with
// SynthRandom::Stream(seed, 3)). Throws InputError (naming `source` if
// given) for an unknown or repeated name, a count that disagrees with
// `holdout`, or more units than can be held out.
std::vector<int> HeldOutUnits(const FaceModel& model,
                              const SynthActorOptions& options,
                              const std::filesystem::path& source = {});

// The options with the hold-out resolved: holdout_units = the held-out
// names (comma-separated, catalog order), holdout = their count. What
// `hmc actor synth` writes to synth.yaml, so the package records which
// units it lacks even if the drawing rule changes.
SynthActorOptions ResolveHoldout(const FaceModel& model,
                                 const SynthActorOptions& options);

// Units that no entry of `plan` activates (ascending). For a plan from
// PlanDataset these are exactly HeldOutUnits: every other unit has its
// 100% extreme in the dataset.
std::vector<int> UnitsNotInDataset(const FaceModel& model,
                                   const std::vector<DatasetEntry>& plan);

// The dataset: every unit at 100% (and, if enabled, in-betweens and
// combinations), in a fixed order, without every entry that activates a
// held-out unit (extremes, in-betweens and combinations alike). With
// options.shapes > 0 the plan is extended to exactly that many entries by
// ExtendDataset; a plan of N shapes is the first N entries of every larger
// one of the same seed. Throws InputError when options.shapes is below the
// standard plan's size.
std::vector<DatasetEntry> PlanDataset(const FaceModel& model,
                                      const SynthActorOptions& options);

// Appends seeded entries to `plan` until it holds `count`: single units at
// in-between levels, and pairs and triples of units that share a region tag
// (a combination of units that move disjoint regions is, at every marker,
// one of its single-unit shapes, so it would add no point to any bundle's
// cloud). Levels are multiples of 0.05 in [0.2, 1]; no entry repeats one
// already in the plan; `held` units are never drawn. Deterministic by
// `seed` (its own random stream), in a fixed order, so a longer extension
// starts with every entry of a shorter one.
void ExtendDataset(const FaceModel& model, const std::vector<int>& held, int seed,
                   int count, std::vector<DatasetEntry>* plan);

// Builds the actor from an already built model (what SynthesizeActor does).
Actor SynthesizeActorFromModel(const FaceModel& model,
                               const SynthActorOptions& options);

// synth.yaml in an actor package: the generator options it was made with,
// so the generator can be rebuilt from the package.
constexpr char kSynthOptionsFile[] = "synth.yaml";
void WriteSynthActorOptions(const SynthActorOptions& options,
                            const std::filesystem::path& actor_dir);
// Throws InputError naming the file if it is missing, malformed or invalid.
SynthActorOptions ReadSynthActorOptions(const std::filesystem::path& actor_dir);

// Throws InputError (naming actor.dir / neutral.obj) unless `model`'s neutral
// has the actor's triangles and its positions within `tolerance_mm`: the
// package is what the generator makes, not edited or stale.
void CheckActorMatchesModel(const Actor& actor, const FaceModel& model,
                            double tolerance_mm);

// How far a package's neutral may be from the regenerated one: WriteActor's
// 9 significant digits on coordinates of ~100 mm give ~1e-7 mm.
constexpr double kSynthPackageToleranceMm = 1e-4;

// A synthetic actor package as the harness commands (`hmc actor frames`,
// `hmc synth shot`, `hmc experiment`) use it: the generator options of its
// synth.yaml (read first: a package without it fails before the slow load),
// the loaded package, and the generator rebuilt from the options, checked
// against the package (CheckActorMatchesModel, kSynthPackageToleranceMm).
struct SynthPackage {
  SynthPackage();
  SynthPackage(SynthPackage&&) noexcept;
  ~SynthPackage();  // FaceModel is complete only in synth_actor.cc
  SynthActorOptions options;
  Actor actor;
  std::unique_ptr<FaceModel> model;
  std::filesystem::path synth_file;  // dir / synth.yaml
};
SynthPackage LoadSynthPackage(const std::filesystem::path& dir);

// The whole synthetic actor as an in-memory package (mm, head space).
// Throws InputError if !options.Check().
Actor SynthesizeActor(const SynthActorOptions& options);

}  // namespace hmc
