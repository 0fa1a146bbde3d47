// Ground-truth test material from the synthetic actor's generator
// (docs/synthetic.md, `hmc actor frames`): activation sequences that the
// dataset never contains (random combinations, an animated performance,
// combinations of held-out units alone or mixed with dataset units), or the
// dataset's own shapes for verification, evaluated to truth meshes, jaw
// poses and (optionally noisy, every kind) marker bundles.
//
// Held-out units are the units no entry of `plan` activates
// (UnitsNotInDataset; for PlanDataset's plan, HeldOutUnits); an empty plan
// holds none out. combos and the
// performance's expression events draw only from the other units, so with
// no held-out unit they are exactly what they were before holdout existed.
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
  std::string kind = "combos";  // dataset | combos | performance | heldout | mixed
  int frames = 120;             // number of frames (combos, performance)
  int seed = 1;                 // random seed of the activations and the noise
  double noise_mm = 0.0;        // std of Gaussian noise per bundle coordinate (mm)
  double fps = 30.0;            // frame rate of the sequence (frames per second)
  int min_units = 2;            // combos: fewest units active per frame
  int max_units = 5;            // combos: most units active per frame
  double min_activation = 0.15;  // combos, heldout, mixed: activations drawn in [min, 1]
  int held_min_units = 1;       // heldout, mixed: fewest held-out units per frame
  int held_max_units = 3;       // heldout, mixed: most held-out units per frame

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

// The kinds TruthFramesOptions::kind accepts, in documentation order.
const std::vector<std::string>& TruthFrameKinds();
// True for the kinds that need held-out units (heldout, mixed).
bool KindNeedsHeldOutUnits(const std::string& kind);

// Activation sequences (K per frame) for `options.kind`; `dataset` replays
// `plan`. combos never repeat a dataset entry. heldout: per frame
// held_min_units..held_max_units distinct held-out units (at most all of
// them); mixed: per frame min_units..max_units units in all (at least 2),
// of which 1..held_max_units held out and at least one a dataset unit.
// Activations uniform in [min_activation, 1]. Throws InputError for
// heldout / mixed if `plan` leaves no unit out.
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
