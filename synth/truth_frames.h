// Ground-truth test material from the synthetic actor's generator
// (DESIGN.md section 6, `hmc actor frames`): activation sequences that the
// dataset never contains (random combinations, an animated performance), or
// the dataset's own shapes for verification, evaluated to truth meshes,
// jaw poses and (optionally noisy) marker bundles.
#pragma once

#include <string>
#include <vector>

#include "core/actor.h"
#include "core/frame_data.h"
#include "core/options.h"
#include "synth/face_model.h"
#include "synth/synth_actor.h"

namespace hmc {

struct TruthFramesOptions {
  std::string kind = "combos";  // dataset | combos | performance
  int frames = 120;             // number of frames (combos, performance)
  int seed = 1;                 // random seed of the activations and the noise
  double noise_mm = 0.0;        // std of Gaussian noise per bundle coordinate (mm)
  double fps = 30.0;            // frame rate of the sequence (frames per second)
  int min_units = 2;            // combos: fewest units active per frame
  int max_units = 5;            // combos: most units active per frame
  double min_activation = 0.15;  // combos: activations drawn in [min, 1]

  void Register(OptionFields* fields);
  bool Check() const;
};

struct TruthFrames {
  std::vector<std::string> labels;          // per frame: shape name or kind
  std::vector<Eigen::VectorXd> activations;  // per frame: K unit activations
  std::vector<MatX3d> positions;             // per frame: V x 3 truth (mm)
  std::vector<JawFrame> jaw;                 // per frame: true jaw pose
  std::vector<BundleFrame> bundles;          // per frame: markers (+ noise)
  int start_frame = 1;                       // number of the first frame
};

// Activation sequences (K per frame) for `options.kind`; `dataset` replays
// `plan`. combos never repeat a dataset entry.
std::vector<Eigen::VectorXd> TruthActivations(
    const FaceModel& model, const std::vector<DatasetEntry>& plan,
    const TruthFramesOptions& options);

// Evaluates the sequence and the markers' bundles (noise seeded by
// options.seed). Frames are numbered from 1.
TruthFrames MakeTruthFrames(const FaceModel& model,
                            const std::vector<Marker>& markers,
                            const std::vector<DatasetEntry>& plan,
                            const TruthFramesOptions& options);

}  // namespace hmc
