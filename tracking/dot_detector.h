// Painted-dot detection in an original (fisheye) frame, never a resampled
// one (docs/tracking.md, "Detection").
//
// 1. Candidates: with B the local mean of the image over a box of
//    `background_scale` dot diameters, a pixel belongs to a dark dot where
//    I < (1 - c) B (bright dots: I > (1 + c) B), c = min_contrast, a
//    relative darkening that does not depend on the lighting, and by at
//    least `min_step` of full scale and 5 noise sigmas (the noise estimated
//    from neighbour differences on lit pixels), so sensor noise, also in
//    the unlit helmet interior, is not a dot. Connected
//    components of that mask are the candidates, at c and again at 2c
//    (which splits a dot from a fainter feature it touches), and a third
//    time against the skin without the dots instead of B: the image closed
//    by a disc a little wider than a dot, since a dark region within the
//    box (beyond a silhouette, a shadowed lid, an eyebrow) drags B down and
//    with it a dot beside it below the threshold. At that level a blob is
//    seeded by pixels at c and grown over those at 0.6 c (the pixels of a
//    dot seen edge-on are only partly covered), and must have skin round
//    three quarters of its ring (step 3), so the seen part of a dot cut by
//    the dark region is not taken for a dot. A later level's blob counts
//    only where the earlier ones found none.
// 2. Rejection by size and shape: from the blob's binary second moments,
//    the ellipse of the same moments (axes 4 sqrt(lambda_i)). A painted disc
//    seen from any angle is an ellipse at most its diameter long: the long
//    axis must be within [min_size, max_size] x the expected diameter, the
//    axis ratio <= max_elongation (7: a disc seen at view cosine 0.14, so
//    dots seen edge-on at the cheeks and under the chin are kept; tested
//    on the darkening's weighted moments after step 3, the binary blob's
//    minor axis given a pixel of slack, since a thin ellipse thresholds to
//    a blob one pixel wide whatever its width) and
//    the blob must fill >= min_fill of its moment ellipse; plus clearance
//    from the image border. This rejects nostrils, the mouth opening and eye
//    sockets (too big), the lip line and lashes (too long), ragged shapes
//    and isolated noise pixels (too small).
// 3. Sub-pixel centre: the skin around the dot is fitted by a plane
//    B(x, y) = a + b x + c y on a ring 1.5-3.5 px outside the blob's
//    ellipse (its moment ellipse scaled to its area; pixels darker than
//    85 % of the ring median dropped), and the centre is the centroid of
//    the relative darkening above the skin texture, w = max(0, (B - I) / B
//    - 0.2 q), q the ellipse's axis ratio (<= 1), over the ellipse grown by
//    1 px (the anti-aliased rim), iterated with the ellipse re-centred;
//    pixels of other blobs are left out. Across a thin ellipse (a dot seen
//    edge-on) every pixel is partly covered, and the floor would be a
//    threshold on the coverage whose centroid locks to the pixel grid:
//    hence its scaling by q; a round window would clip such a dot and a
//    round ring would hold its ends. Dividing by B makes w flat over the
//    painted disc whatever the shading, so a light gradient does not pull
//    the centroid; the centroid of a uniform anti-aliased disc is its area
//    centroid, which is what dots_2d.csv's cx, cy give.
// Score in [0, 1]: contrast (relative to 0.5) times roundness.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "core/options.h"
#include "core/types.h"

namespace hmc {

struct DotDetectorOptions {
  std::string polarity = "dark";  // dark (paint darker than the skin) | bright
  double dot_size_px = 0;         // expected dot diameter (px; 0 = measured at the reference frame)
  double min_contrast = 0.25;     // relative darkening (or brightening) of a dot pixel vs the local mean
  double min_step = 0.03;         // smallest absolute darkening of a dot pixel (fraction of full scale)
  double min_size = 0.45;         // smallest equivalent diameter (fraction of the expected)
  double max_size = 1.9;          // largest equivalent diameter (fraction of the expected)
  double max_elongation = 7;      // largest ratio of the blob's axes (a disc seen at 82 deg, cos 0.14)
  double min_fill = 0.6;          // smallest fraction of the blob's moment ellipse covered
  double background_scale = 4;    // box of the local mean (dot diameters)
  int border_px = 3;              // clearance from the image border (px)

  void Register(OptionFields* fields);
  bool Check() const;
};

struct DotDetection {
  Vec2 pixel = Vec2::Zero();  // sub-pixel centre (px, OpenCV pixel centres)
  double diameter_px = 0;     // long axis of the thresholded blob (px)
  double contrast = 0;        // mean relative darkening inside the dot
  double elongation = 1;      // axis ratio of the darkening's second moments
  double score = 0;           // quality in [0, 1]
};

// Detects dots of about `dot_size_px` diameter in `grey` (CV_8U, CV_16U or
// CV_32F in [0, 1]). Sorted by y then x.
std::vector<DotDetection> DetectDots(const cv::Mat& grey, const DotDetectorOptions& options,
                                     double dot_size_px);

// A dot where the tracker expects one (marker_tracker.h): its predicted
// centre, how far off it may be, and the ellipse its surface normal
// predicts (docs/tracking.md, "Searching for an expected dot").
struct ExpectedDot {
  Vec2 pixel = Vec2::Zero();          // predicted centre (px)
  double radius_px = 0;               // search radius around it (px)
  double axis_ratio = 1;              // predicted short / long axis: the view cosine
  Vec2 short_axis = Vec2(1, 0);       // unit image direction of the short axis (the normal's)
};

// Searches for the one dot expected at `expected`: in a patch around it,
// against the closed skin as at DetectDots' third level, seeds at half its
// contrast and noise margin (the search looks only where a dot is due),
// the blob's size and shape tested as by DetectDots, its centre refined
// the same way; the dot must lie across its projected normal when thin.
// Nothing when two blobs lie within the radius (ambiguous). With no blob,
// the dot is sought by the matched filter of its
// predicted ellipse (a plane plus the ellipse's pixel coverage, fitted by
// least squares over its centre within 1 px of the prediction), taken
// where significant against the window's own texture and not a line
// running on beyond the ellipse's ends.
std::optional<DotDetection> DetectDotNear(const cv::Mat& grey, const DotDetectorOptions& options,
                                          double dot_size_px, const ExpectedDot& expected);

// The dot diameter of a frame: detection with a wide size range (2 to 16
// px), then the median diameter of the round, well-filled blobs. Returns 0
// when fewer than 8 such blobs are found.
double MeasureDotSize(const cv::Mat& grey, const DotDetectorOptions& options);

}  // namespace hmc
