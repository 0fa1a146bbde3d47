// `hmc eval`'s work: how far a reconstructed mesh sequence is from the
// truth, per frame and pooled (eval/eval_metrics.h), with the files of
// docs/formats.md, "hmc eval outputs": eval.json, per_frame.csv,
// error_uv_mean.exr and, per pictured frame, error_uv_NNNNNN.exr and
// frame_NNNNNN.png (eval/error_pictures.h), plus what options_used.yaml
// needs from the caller.
#pragma once

#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/actor.h"
#include "core/mesh_metrics.h"
#include "core/mesh_sequence.h"
#include "core/options.h"
#include "eval/eval_metrics.h"
#include "eval/picture_options.h"

namespace hmc {

struct EvalOptions {
  MeshMetricsOptions metrics;
  int uv_resolution = 512;  // side of the UV-space error maps (px)
  double markers_radius_mm = 15.0;  // with EvalInput::at_markers: "near" is
                                    // within this of a listed marker (mm)
  PictureOptions picture;

  void Register(OptionFields* fields);
  bool Check() const;
};

// The frames two sequences share, matched by frame number: (index in a,
// index in b) and the frame number, in a's order.
struct FrameMatch {
  std::vector<std::pair<int, int>> pairs;
  std::vector<int> numbers;
};
FrameMatch MatchFrames(const MeshSequence& a, const MeshSequence& b);

struct EvalInput {
  const Actor* actor = nullptr;
  std::filesystem::path truth, recon;  // mesh sequences (any format)
  std::filesystem::path bundles;  // bundles.csv for the bundle residual, or
                                  // empty: the truth's marker points
  std::filesystem::path out;  // output folder, or empty: no files
  std::vector<int> picture_frames;  // frame numbers to picture (with out);
                                    // empty: four spread over the sequence
  // Optional (frame number, marker name) pairs, e.g. rays.csv's markers
  // seen by one camera: the report's "at_markers" gives the error at their
  // surface points and, in their frames, over the face near them and away
  // from them and at the other markers (docs/formats.md, "hmc eval outputs").
  std::vector<std::pair<int, std::string>> at_markers;
  std::filesystem::path at_markers_file;  // names them in errors
};

struct EvalOutput {
  int frames = 0;  // matched frames
  SequenceMetrics metrics;
  nlohmann::json report;  // eval.json's object
  std::string BriefReport() const;
};

// Throws InputError naming the file when a sequence does not fit the actor,
// the sequences share no frame number, or a picture frame is not in both.
EvalOutput RunEval(const EvalInput& input, const EvalOptions& options);

}  // namespace hmc
