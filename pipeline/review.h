// `hmc review --work WORK [--out WORK/review]`: a static page to scrub a
// run, see the solved mesh in 3D and fix the tracks (docs/review.md).
// Writes OUT/index.html with its scripts (the page's own, and three.js
// from Debian's libjs-three, copied into the build at configure time: no
// network), footage proxies (per camera and frame a JPEG, cropped to the
// named dots and downscaled) and the run's data as scripts the page loads
// on demand: the mesh sequence in chunks of frames (int16 displacements
// from the neutral, base64), the tracks with their state, the bundles
// with their solve residual, the report's plots and warnings (formats:
// docs/formats.md, "Review").
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>

#include "core/options.h"

namespace hmc {

struct ReviewOptions {
  int proxy_height = 360;         // height of the footage proxies (px)
  int jpeg_quality = 80;          // JPEG quality of the proxies (1-100)
  int chunk_frames = 8;           // frames per data chunk the page loads at a time
  double error_max_mm = 0.5;      // top of the error-against-truth colour scale (mm)
  double residual_max_mm = 0.5;   // top of the bundle-residual colour scale (mm)

  void Register(OptionFields* fields);
  bool Check() const;
};

struct ReviewInput {
  std::filesystem::path work;  // the run's workspace
  std::filesystem::path out;   // folder to write the page into
  // The shot folder (footage, ground truth); empty: the one the run
  // recorded in its stage summaries (`run_inputs`).
  std::filesystem::path shot;
};

struct ReviewSummary {
  int frames = 0;               // frames of the page's cursor
  int cameras = 0;
  int proxies = 0;              // proxy images written
  int64_t proxy_bytes = 0;      // their size
  int64_t footage_bytes = 0;    // the footage files' size
  int64_t data_bytes = 0;       // the data scripts' size (mesh chunks included)
  bool has_mesh = false;
  bool has_truth = false;       // the mesh error against the shot's truth is shown
  double seconds = 0;
  std::string BriefReport() const;
};

// Throws InputError naming the file for a workspace without tracks, an
// unreadable file, or a shot it cannot find.
ReviewSummary WriteReview(const ReviewInput& input, const ReviewOptions& options);

// The page's static files (index.html, review.js, review.css, three.min.js,
// OrbitControls.js): $HMC_REVIEW_ASSETS if set, else share/hmc/review
// beside the executable's bin/ (the build tree and an install both have
// it). Throws InputError when the folder lacks them.
std::filesystem::path ReviewAssetsDir();

}  // namespace hmc
