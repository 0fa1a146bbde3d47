// `hmc experiment`'s runner: the side-by-side comparison of every solve
// method on held-out material from the synthetic actor's generator
// (docs/baselines.md). For each kind of material (dataset = verification,
// combos, performance, heldout, mixed) and each marker-noise level, the
// material is generated with the library `hmc actor frames` uses
// (synth/truth_frames.h), every method is run on it through
// blending/solve_method.h (as `hmc solve --method`), and the results are
// measured with the code of `hmc eval` (eval/eval_metrics.h). Kinds that
// need held-out units are skipped (with a warning) for an actor that holds
// none out.
//
// The material goes through its files: bundles.csv and jaw.csv are written
// and read back, and truth and reconstructions are rounded to float32 as
// the PC2 files hold them, so `hmc solve` / `hmc eval` on the written files
// give the same numbers.
//
// Writes to the output folder (docs/formats.md, "hmc experiment outputs"):
//   results.md, results.json    the table: material x noise x method
//   <material>/bundles.csv, jaw.csv, labels.csv
//   <material>/truth.pc2, <method>.pc2   with write_meshes: true
//   images/<material>_<method>.png       truth | reconstruction | error
// (options_used.yaml is the caller's: it holds the caller's flags.)
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "blending/solve_method.h"
#include "core/mesh_metrics.h"
#include "core/options.h"
#include "eval/eval_metrics.h"
#include "eval/picture_options.h"

namespace hmc {

struct ExperimentOptions {
  std::vector<std::string> kinds = {"dataset", "combos", "performance",
                                    "heldout", "mixed"};  // material kinds
      // (synth/truth_frames.h); heldout and mixed are skipped for an actor
      // without held-out units
  std::vector<double> noise_mm = {0, 0.1, 0.2, 0.5, 1};  // marker noise
      // levels: std per bundle coordinate (mm)
  std::vector<std::string> methods = {"robust",     "lgi",
                                      "blendshape", "blendshape-bounded",
                                      "interp",     "lgi-rbf",
                                      "robust-global"};
      // robust-global (robust without the local data) gives the table's
      // "local gain" column
  int default_frames = 30;  // frames of a kind not listed in `frames`
  std::vector<std::string> frames = {"combos:30", "performance:60",
                                     "heldout:30", "mixed:30"};
      // frames per kind, kind:count (dataset: all shapes)
  double fps = 30.0;        // frame rate of the material (frames per second)
  bool write_meshes = false;  // write truth.pc2 and <method>.pc2 per material
  std::string picture_kind = "combos";  // material pictured (first noise level)
  int picture_frame = 1;                // its frame number pictured
  PictureOptions picture{320, 400};
  MeshMetricsOptions metrics;
  MethodOptions solve;

  void Register(OptionFields* fields);
  bool Check() const;
  // Frames of material of `kind` (`frames`' entry, else default_frames).
  int FramesOf(const std::string& kind) const;
};

// One row of the table: one method on one material.
struct ExperimentRow {
  std::string kind;
  double noise_mm = 0;
  std::string material;
  std::string method;
  int frames = 0;
  int bad_frames = 0;
  double solve_ms_per_frame = 0;
  // The share of observed bundle-frames that took the local (lgi) answer,
  // from the method's report (robust); < 0: the method has none.
  double local_share = -1;
  // The lag-1 correlation of the material's markers and whether the method
  // treated its frames as a take (robust); correlation < -1: none.
  double take_correlation = -2;
  bool take = false;
  SequenceMetrics metrics;  // without per_frame
};

struct ExperimentInput {
  std::filesystem::path actor_dir;  // a synthetic actor package
  std::filesystem::path out;        // output folder
  int seed = 1;  // seed of the material's activations and marker noise
};

struct ExperimentOutput {
  std::vector<ExperimentRow> rows;
  double seconds = 0;  // wall time
  std::string BriefReport() const;
};

// Throws InputError naming the file for a package that is not the
// generator's (synth/synth_actor.h, LoadSynthPackage).
ExperimentOutput RunExperiment(const ExperimentInput& input,
                               const ExperimentOptions& options);

}  // namespace hmc
