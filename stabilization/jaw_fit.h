// `hmc jaw`: the jaw pose per frame in the actor's jaw-rig parameters
// (open_deg, lateral_deg, protrude_mm; core/jaw.h) from head-space bundles
// (method and measured accuracy: docs/stabilization.md, "The jaw fit").
//
// Model of marker k (stabilization/marker_model.h): the skin's expression
// is a blend of the dataset's shapes unskinned by their own jaw poses,
// u_k(c) = x0(s_k) + B*_k c (c: N global shape weights), skinned by the
// frame's jaw pose theta: p_k = S_k(T(theta), u_k(c)). Per frame,
//   min_{theta, c}  sum_{k in J} |p_k - S_k(T(theta), u_k(c))|^2
//                   + sum_{k} |S_k^-1(p_k) - u_k(c)|^2 + lambda |c|^2
// with J the jaw markers (tagged `jaw`: chin, jaw line) and the lower lip,
// by variable projection (Golub & Pereyra 1973): for a given theta, c is
// the ridge least-squares fit to all markers' unskinned bundles (one
// precomputed Cholesky factor), c*(theta); Ceres minimises the first term
// at c*(theta) over theta alone within bounds (the dataset's jaw poses,
// widened by bound_margin of their range). Alternating the two steps
// instead converges slowly: the shapes and the jaw both move the chin. Then a temporal prior over the sequence (smoothness > 0):
//   min sum_f (theta_f - th_f)^T H_f (theta_f - th_f)
//       + mu sum_f |theta_{f-1} - 2 theta_f + theta_{f+1}|^2
// with th_f, H_f = J^T J the per-frame estimate and its Gauss-Newton
// information (the Laplace approximation of the frame's data term), solved
// with Ceres over all frames; a frame without enough jaw markers has no
// data term there and is filled by the prior (linearly when mu = 0).
// A fit on markedly fewer jaw markers than the shot's frames usually have
// (min_marker_fraction of the median count), or (when max_residual_ratio
// > 0) whose residual is far above theirs, is not trusted either:
// where the tracker loses jaw markers for a stretch, the fits at its ends
// rest on the few left and can be far off, and they would anchor the
// stretch's interpolation (docs/stabilization.md, "Unreliable fits").
#pragma once

#include <array>
#include <filesystem>
#include <string>
#include <vector>

#include "core/frame_data.h"
#include "core/day_markers.h"
#include "core/options.h"
#include "stabilization/marker_model.h"

namespace hmc {

// What to optimise.
struct JawOptions {
  DayMarkersOptions day;         // markers: the day's markers (core/day_markers.h)
  double smoothness = 0.01;      // mu: temporal prior on second differences (mm^2 per deg^2, or per mm^2 for protrude)
  double bound_margin = 0.25;    // bounds: the dataset's jaw range widened by this fraction of it (at least 1 deg / 1 mm) on each side
  double ridge = 0.1;            // lambda: ridge on the global shape weights (mm^2 per unit weight^2)
  int min_jaw_markers = 2;       // fewer jaw markers present: the frame is interpolated (docs/stabilization.md)
  double min_marker_fraction = 0;  // fewer than this fraction of the shot's median jaw-marker count: the fit is not trusted (interpolated; 0 = off, docs/stabilization.md)
  double max_residual_ratio = 0;  // > 0: a residual above this many times the shot's median residual: the fit is not trusted (interpolated); 0 = off
  std::string lip_prefix = "mouth_lower";  // markers named so (or tagged lower_lip) join the jaw markers
  int max_solver_iterations = 20;  // Ceres iterations per frame
  int threads = 0;               // worker threads (0 = all cores)

  void Register(OptionFields* fields);
  bool Check() const;
};

struct JawFit {
  int frame = 0;
  JawPose pose;
  bool ok = false;        // false: interpolated (see reason)
  std::string reason;
  int jaw_markers = 0;    // jaw markers present
  double rms_mm = 0;      // RMS residual over the jaw markers (mm)
  Mat3 information = Mat3::Zero();  // H_f = J^T J at the estimate (per unit^2)
};

struct JawOutput {
  std::vector<JawFit> frames;
  std::array<double, 3> lower{}, upper{};  // bounds used
  int num_ok = 0;
  int num_interpolated = 0;
  double mean_rms_mm = 0;
  double seconds = 0;
  std::string BriefReport() const;
  std::vector<JawFrame> JawFrames() const;
};

// The jaw markers J (indices into the model's markers).
std::vector<int> JawMarkers(const MarkerModel& model, const Actor& actor,
                            const JawOptions& options);

// Throws InputError if the actor has no jaw rig or the options are invalid.
JawOutput RunJaw(const Actor& actor, const MarkerModel& model,
                 const std::vector<BundleFrame>& bundles,
                 const JawOptions& options);

// Writes jaw.csv at `path` and, beside it, <stem>_options_used.yaml and
// (last) <stem>_summary.json.
void WriteJawOutput(const JawOutput& output, const JawOptions& options,
                    const std::filesystem::path& path);

}  // namespace hmc
