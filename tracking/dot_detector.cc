#include "tracking/dot_detector.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <opencv2/imgproc.hpp>

namespace hmc {

void DotDetectorOptions::Register(OptionFields *fields) {
  fields->Add("polarity", &polarity, "dark (paint darker than the skin) | bright")
      .OneOf({"dark", "bright"});
  fields->Add("dot_size_px", &dot_size_px,
              "expected dot diameter (px; 0 = measured at the reference frame)")
      .In(0, 40);
  fields->Add("min_contrast", &min_contrast,
              "relative darkening (or brightening) of a dot pixel vs the local mean")
      .Above(0).Below(1);
  fields->Add("min_step", &min_step,
              "smallest absolute darkening of a dot pixel (fraction of full scale)")
      .AtLeast(0).Below(1);
  fields->Add("min_size", &min_size, "smallest equivalent diameter (fraction of the expected)")
      .Above(0).Below(1);
  fields->Add("max_size", &max_size, "largest equivalent diameter (fraction of the expected)")
      .Above(1);
  fields->Add("max_elongation", &max_elongation,
              "largest ratio of the blob's axes (a disc seen at 82 deg, cos 0.14)")
      .AtLeast(1);
  fields->Add("min_fill", &min_fill, "smallest fraction of the blob's moment ellipse covered")
      .AtLeast(0).Below(1);
  fields->Add("background_scale", &background_scale, "box of the local mean (dot diameters)")
      .AtLeast(2);
  fields->Add("border_px", &border_px, "clearance from the image border (px)").AtLeast(0);
}

bool DotDetectorOptions::Check() const {
  CHECK_OPTION_LIMITS();
  CHECK_OPTION(dot_size_px == 0 || dot_size_px >= 1.5);
  return true;
}

namespace {

cv::Mat AsFloat(const cv::Mat &grey) {
  if (grey.type() == CV_32F) return grey;
  cv::Mat out;
  grey.convertTo(out, CV_32F, grey.depth() == CV_16U ? 1.0 / 65535 : 1.0 / 255);
  return out;
}

// The side of the closing's disc (odd): a dot's diameter + 2 px.
int ClosingSide(double dot_size_px) { return static_cast<int>(std::ceil(dot_size_px) + 2) | 1; }

struct Refined {
  bool ok = false;
  Vec2 centre = Vec2::Zero();
  double contrast = 0;
  double elongation = 1;
};

// Background plane on an annulus, then the iterated centroid of the
// relative darkening (file comment, step 3). sign = +1 dark, -1 bright.
// Relative darkening below this is skin texture (the albedo varies by about
// +-10 %), not paint: it is subtracted before the centroid, so texture
// outside the dot carries no weight while the disc's (symmetric)
// anti-aliased rim keeps a symmetric weight.
constexpr double kTextureFloor = 0.2;

// A dot pixel's darkening, in sensor-noise sigmas (a 5-sigma pixel is a
// 1-in-3.5-million event of Gaussian noise).
constexpr double kNoiseSigmas = 5;

// Largest fraction of the background ring that may be darker than 85 % of
// its median. A blob found only against the closed skin lies by a dark
// region by construction, and the closing also finds the seen part of a
// dot cut by that region (a silhouette, a lid), whose centroid is not the
// dot's and whose ring holds the dark region over about half its length:
// such blobs must have skin round three quarters of their ring (a thin
// ellipse beside the edge keeps its ring, 1.5-3.5 px out, off it; and the
// rim of a dark region wider than the closing, which the closing does not
// quite follow, has the region in most of its ring).
constexpr double kMaxRingIntrusion = 0.5;
constexpr double kMaxRingIntrusionBesideDark = 0.25;

// The closed-skin level's hysteresis: blobs seeded at min_contrast grow
// over the pixels darker than this fraction of it.
constexpr double kGrowContrast = 0.6;

// The background ring of a dot's centroid reaches this far beyond its
// ellipse (px).
constexpr double kRingOut = 3.5;

// The search for an expected dot (DetectDotNear): its seeds need this
// fraction of the blind levels' contrast and noise margin, since a thin
// dot's pixels are only partly covered and the search looks only where a
// dot is expected, not over the whole frame.
constexpr double kGuidedContrast = 0.5;
// A dot expected thinner than this axis ratio and found elongated must
// lie across its projected normal: its long axis within asin(0.5) = 30
// degrees of the expected one.
constexpr double kGuidedOrientedRatio = 0.6;
constexpr double kGuidedMaxAxisSine = 0.5;
// A dot found by the matched filter of its predicted ellipse (FitTemplate)
// must stand out of the window's texture by this many standard errors: the
// statistic is the largest over ~100 centres tried, whose null maximum
// under Gaussian noise stays under 4, and skin texture is not Gaussian.
constexpr double kTemplateMinSnr = 5;
// ... within this of the prediction (px): the tracker places an expected
// dot within 0.1-0.3 px (median, docs/tracking.md); a faint optimum
// farther off (on its search disc's rim: beyond 0.75 px) is the skin's
// texture, a brow's hair or a lid's edge more often than the dot (measured
// on fresh shots: 0 of ~950 fits within 0.75 px were over 1 px off any dot,
// against a third of those farther).
constexpr double kTemplateMaxOffset = 1.0;
// ... and the strips beyond its ends at most this dark relative to its
// middle (TemplateFit::end_ratio): a line (a crease, a lash, a lid's or a
// lip's edge) along the predicted ellipse fits it as well as a dot, but
// goes on beyond its ends, where a dot's anti-aliased tips and blur leave
// a small fraction of its middle's darkening.
constexpr double kTemplateMaxEndRatio = 0.5;
// ... and its fitted paint darkening at most this: a relative darkening is
// at most 1, with slack for a dot wider than predicted (the neutral's
// normal is not the posed face's); a wide dark thing fitted with a thin
// template reads darker.
constexpr double kTemplateMaxContrast = 1.5;
// The expected dot is at most this many diameters long (the blind levels
// allow 1.9, for dots nearer the lens than most): beside a lid or a lip a
// longer blob is the dot joined to their dark edge, whose centroid is not
// the dot's.
constexpr double kGuidedMaxLength = 1.3;

// The blob's shape: the ellipse of its binary second moments, scaled to
// the blob's area (semi-axes a >= b, a b = area / pi; a = b = the
// equivalent radius for a round blob), long axis along (ux, uy).
struct BlobEllipse {
  double a = 1, b = 1;
  double ux = 1, uy = 0;
  // Whether offset (dx, dy) from the centre lies inside the ellipse grown
  // by g px along both axes.
  bool Inside(double dx, double dy, double g) const {
    const double u = (ux * dx + uy * dy) / (a + g), v = (-uy * dx + ux * dy) / (b + g);
    return u * u + v * v <= 1;
  }
};

// The pixels within `reach` of `centre` along both axes (inclusive
// bounds); false where they leave the image.
bool ReachBox(const cv::Mat &image, const Vec2 &centre, double reach, int *x0, int *x1, int *y0,
              int *y1) {
  *x0 = static_cast<int>(std::floor(centre.x() - reach));
  *x1 = static_cast<int>(std::ceil(centre.x() + reach));
  *y0 = static_cast<int>(std::floor(centre.y() - reach));
  *y1 = static_cast<int>(std::ceil(centre.y() + reach));
  return *x0 >= 0 && *y0 >= 0 && *x1 < image.cols && *y1 < image.rows;
}

// Pixels of other blobs (labels other than 0 and `own`) are left out of
// both the background ring and the centroid. The ring and the window
// follow the blob's ellipse, so that a dot seen edge-on (a thin ellipse)
// is neither clipped by a round window nor has its own ends in its ring.
Refined RefineCentre(const cv::Mat &image, const cv::Mat &labels, int own, Vec2 centre,
                     const BlobEllipse &shape, double sign, double max_intrusion) {
  Refined out;
  const double ring_in = 1.5, ring_out = kRingOut, window = 1.0;  // px beyond the ellipse
  const double reach = shape.a + ring_out;
  // The texture floor, scaled by the blob's axis ratio: across a thin
  // ellipse (a dot seen edge-on) every pixel is partly covered, and a
  // floor on the darkening is then a threshold on the coverage whose
  // result locks to the pixel grid (0.1-0.2 px on a 6:1 ellipse, measured
  // in tracking/dot_detector_test.cc); a round dot keeps the whole floor.
  const double floor = kTextureFloor * shape.b / shape.a;
  for (int iteration = 0; iteration < 3; ++iteration) {
    int x0, x1, y0, y1;
    if (!ReachBox(image, centre, reach, &x0, &x1, &y0, &y1)) return out;
    std::vector<float> ring;
    std::vector<Eigen::Vector3d> ring_points;
    for (int y = y0; y <= y1; ++y) {
      const float *row = image.ptr<float>(y);
      const int *label = labels.ptr<int>(y);
      for (int x = x0; x <= x1; ++x) {
        const double dx = x - centre.x(), dy = y - centre.y();
        if (label[x] == 0 && shape.Inside(dx, dy, ring_out) && !shape.Inside(dx, dy, ring_in)) {
          ring.push_back(row[x]);
          ring_points.emplace_back(x - centre.x(), y - centre.y(), row[x]);
        }
      }
    }
    if (ring.size() < 8) return out;
    std::vector<float> sorted = ring;
    std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
    const double median = sorted[sorted.size() / 2];
    if (!(median > 1e-4)) return out;
    Eigen::Matrix3d normal = Eigen::Matrix3d::Zero();
    Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
    int intruded = 0;
    for (const Eigen::Vector3d &p : ring_points) {
      // Drop intrusions of the dot's own polarity (a neighbour, a crease).
      if (sign > 0 ? p.z() < 0.85 * median : p.z() > median / 0.85) {
        ++intruded;
        continue;
      }
      const Eigen::Vector3d a(1, p.x(), p.y());
      normal += a * a.transpose();
      rhs += a * p.z();
    }
    // Skin must surround a painted dot: where much of the ring is dark
    // (the face's silhouette, the lip line, an eyelid), the dot is cut by
    // an occluding edge and its centroid is not the dot's.
    if (intruded > max_intrusion * ring_points.size()) return out;
    const Eigen::Vector3d plane = normal.ldlt().solve(rhs);
    if (!plane.allFinite()) return out;
    double sw = 0, sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0;
    int count = 0;
    for (int y = y0; y <= y1; ++y) {
      const float *row = image.ptr<float>(y);
      const int *label = labels.ptr<int>(y);
      for (int x = x0; x <= x1; ++x) {
        const double dx = x - centre.x(), dy = y - centre.y();
        if (!shape.Inside(dx, dy, window)) continue;
        if (label[x] != 0 && label[x] != own) continue;
        const double b = plane(0) + plane(1) * dx + plane(2) * dy;
        if (!(b > 1e-4)) continue;
        const double w = std::max(0.0, sign * (b - row[x]) / b - floor);
        sw += w;
        sx += w * dx;
        sy += w * dy;
        sxx += w * dx * dx;
        syy += w * dy * dy;
        sxy += w * dx * dy;
        ++count;
      }
    }
    if (!(sw > 0) || count == 0) return out;
    const Vec2 shift(sx / sw, sy / sw);
    centre += shift;
    const double cxx = sxx / sw - shift.x() * shift.x();
    const double cyy = syy / sw - shift.y() * shift.y();
    const double cxy = sxy / sw - shift.x() * shift.y();
    const double tr = cxx + cyy, det = cxx * cyy - cxy * cxy;
    const double disc = std::sqrt(std::max(0.0, tr * tr / 4 - det));
    const double l1 = tr / 2 + disc, l2 = tr / 2 - disc;
    out.elongation = l2 > 1e-9 ? std::sqrt(l1 / l2) : 1e9;
    out.contrast = sw / (M_PI * shape.a * shape.b) + floor;
    if (shift.norm() < 1e-3) break;
  }
  out.ok = true;
  out.centre = centre;
  return out;
}

// The shape of blob `label` (binary mask in `labels`, bounding box `box`,
// `area` pixels): the ellipse of its binary second moments (axes 4
// sqrt(lambda_i)), scaled to its area for the centroid's window.
struct BlobShape {
  Vec2 centre = Vec2::Zero();  // binary centroid (px)
  double major = 0, minor = 0;  // axes of the moment ellipse (px)
  double radius = 0;            // equivalent radius, sqrt(area / pi) (px)
  BlobEllipse ellipse;
};

BlobShape MeasureBlob(const cv::Mat &labels, int label, const cv::Rect &box, int area) {
  double sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0;
  for (int y = box.y; y < box.y + box.height; ++y) {
    const int *row = labels.ptr<int>(y);
    for (int x = box.x; x < box.x + box.width; ++x) {
      if (row[x] != label) continue;
      sx += x;
      sy += y;
      sxx += static_cast<double>(x) * x;
      syy += static_cast<double>(y) * y;
      sxy += static_cast<double>(x) * y;
    }
  }
  BlobShape out;
  const double mx = sx / area, my = sy / area;
  const double cxx = sxx / area - mx * mx + 1.0 / 12, cyy = syy / area - my * my + 1.0 / 12;
  const double cxy = sxy / area - mx * my;
  const double tr = cxx + cyy, det = cxx * cyy - cxy * cxy;
  const double disc = std::sqrt(std::max(0.0, tr * tr / 4 - det));
  out.centre = Vec2(mx, my);
  out.major = 4 * std::sqrt(tr / 2 + disc);
  out.minor = 4 * std::sqrt(std::max(1e-9, tr / 2 - disc));
  out.radius = std::sqrt(area / M_PI);
  out.ellipse.a = out.radius * std::sqrt(out.major / out.minor);
  out.ellipse.b = out.radius * std::sqrt(out.minor / out.major);
  const double angle = 0.5 * std::atan2(2 * cxy, cxx - cyy);
  out.ellipse.ux = std::cos(angle);
  out.ellipse.uy = std::sin(angle);
  return out;
}

// A painted disc seen at any angle is at most its diameter long (the lip
// line and lashes are longer), an ellipse (fill of its moment ellipse near
// 1), and not thinner than max_elongation. The thresholded blob of a thin
// ellipse can be a single pixel wide (minor 1.15 px) where the ellipse is
// up to a pixel wider (its partly covered rim falls below the threshold),
// so the ratio is tested here with that pixel added and again, exactly,
// on the darkening's own moments after the centroid.
bool PlausibleDot(const BlobShape &blob, int area, double min_d, double max_d,
                  const DotDetectorOptions &options) {
  if (blob.major < min_d || blob.major > max_d ||
      blob.major > options.max_elongation * (blob.minor + 1)) {
    return false;
  }
  return area >= options.min_fill * M_PI / 4 * blob.major * blob.minor;
}

DotDetection MakeDetection(const Refined &refined, const Vec2 &offset, double major) {
  DotDetection dot;
  dot.pixel = refined.centre + offset;
  dot.diameter_px = major;
  dot.contrast = refined.contrast;
  dot.elongation = refined.elongation;
  dot.score = std::clamp(refined.contrast / 0.5, 0.0, 1.0) *
              std::clamp(1.0 / refined.elongation, 0.0, 1.0);
  return dot;
}

// The sensor noise sigma, from horizontal neighbour differences on lit
// pixels (every 4th row): for independent noise, I(x+1) - I(x) has std
// sqrt(2) sigma, and its median absolute value is 0.6745 of that std.
double EstimateNoise(const cv::Mat &image, int row_step = 4) {
  std::vector<float> diffs;
  for (int y = 0; y < image.rows; y += row_step) {
    const float *row = image.ptr<float>(y);
    for (int x = 0; x + 1 < image.cols; x += 2) {
      if (row[x] > 0.1f) diffs.push_back(std::abs(row[x + 1] - row[x]));
    }
  }
  if (diffs.size() < 50) return 0;
  std::nth_element(diffs.begin(), diffs.begin() + diffs.size() / 2, diffs.end());
  return diffs[diffs.size() / 2] / (0.6745 * std::sqrt(2.0));
}

// The skin without the dots: the image closed (opened, for bright dots)
// by a disc a little wider than a dot, so that no dot, however seen,
// holds it; dark structures wider than the disc (the dark beyond a
// silhouette, a shadowed lid, an eyebrow, a nostril) stay. A square's
// corners would not follow a round dark region, whose rim would then
// read as darker than the skin.
// The disc is a regular octagon, a square (separable) grown by a
// diamond (iterated 3 x 3 crosses), several times faster than a true
// disc; a round region's rim departs from it by under half a pixel.
// On the frame's own type (8 or 16 bit: several times faster than on
// floats); the closing commutes with the conversion, which is monotonic.
// Returns floats in [0, 1].
cv::Mat ClosedSkin(const cv::Mat &grey, double dot_size_px, double sign) {
  const int close_side = ClosingSide(dot_size_px);
  const int diamond = static_cast<int>(std::lround(0.293 * close_side));
  const cv::Mat square = cv::getStructuringElement(
      cv::MORPH_RECT, cv::Size(close_side - 2 * diamond, close_side - 2 * diamond));
  const cv::Mat cross = cv::getStructuringElement(cv::MORPH_CROSS, cv::Size(3, 3));
  auto grow = [&](const cv::Mat &in, cv::Mat *result, int op) {
    cv::morphologyEx(in, *result, op, square, cv::Point(-1, -1), 1, cv::BORDER_REPLICATE);
    if (diamond > 0) {
      cv::morphologyEx(*result, *result, op, cross, cv::Point(-1, -1), diamond,
                       cv::BORDER_REPLICATE);
    }
  };
  cv::Mat skin;
  grow(grey, &skin, sign > 0 ? cv::MORPH_DILATE : cv::MORPH_ERODE);
  grow(skin, &skin, sign > 0 ? cv::MORPH_ERODE : cv::MORPH_DILATE);
  return AsFloat(skin);
}

// The pixels darker (brighter, sign -1) than `background` by `c` relative
// and `s` absolute seed blobs, grown over those at kGrowContrast of both
// (one pass gives the grown mask and the seeds).
void HysteresisMask(const cv::Mat &image, const cv::Mat &background, double contrast, double step,
                    double sign, cv::Mat *mask, std::vector<cv::Point> *seeds) {
  mask->create(image.size(), CV_8U);
  const float c = static_cast<float>(contrast), s = static_cast<float>(step);
  const float grown_c = static_cast<float>(kGrowContrast) * c;
  const float grown_s = static_cast<float>(kGrowContrast) * s;
  const float polarity = static_cast<float>(sign);
  for (int y = 0; y < image.rows; ++y) {
    const float *row = image.ptr<float>(y);
    const float *b = background.ptr<float>(y);
    uchar *m = mask->ptr<uchar>(y);
    for (int x = 0; x < image.cols; ++x) {
      const float darkening = polarity * (b[x] - row[x]);  // brightening for bright dots
      m[x] = darkening > std::max(grown_c * b[x], grown_s) ? 255 : 0;
    }
    for (int x = 0; x < image.cols; ++x) {
      if (m[x] && polarity * (b[x] - row[x]) > std::max(c * b[x], s)) seeds->emplace_back(x, y);
    }
  }
}

std::vector<DotDetection> Detect(const cv::Mat &grey, const DotDetectorOptions &options,
                                 double dot_size_px, double min_d, double max_d) {
  const cv::Mat image = AsFloat(grey);
  // A dot pixel is darker than the local mean by at least min_step and by
  // kNoiseSigmas noise sigmas (noise blobs are not dots).
  const double step = std::max(options.min_step, kNoiseSigmas * EstimateNoise(image));
  const double sign = options.polarity == "bright" ? -1 : 1;
  int box = static_cast<int>(std::lround(options.background_scale * dot_size_px)) | 1;
  box = std::max(box, 7);
  cv::Mat mean;
  cv::boxFilter(image, mean, CV_32F, cv::Size(box, box), cv::Point(-1, -1), true,
                cv::BORDER_REPLICATE);
  const cv::Mat skin = ClosedSkin(grey, dot_size_px, sign);
  std::vector<DotDetection> out;
  // Three levels: the blobs at min_contrast, then at twice it, which splits
  // a dot from a fainter dark feature it touches (an eyelid crease, the lip
  // line), then at min_contrast against the closed skin instead of the box
  // mean, which a dark region within the box drags down: a dot next to a
  // silhouette, on a shadowed lid or by an eyebrow (issue 44). A later
  // level's blob counts only where the earlier ones found none.
  const double levels[3] = {options.min_contrast, std::min(0.9, 2 * options.min_contrast),
                            options.min_contrast};
  size_t earlier_count = 0;
  for (int level = 0; level < 3; ++level) {
    const double contrast = levels[level];
    const cv::Mat &background = level == 2 ? skin : mean;
    earlier_count = out.size();
    // The pixels darker (brighter) than the background by `c` relative and
    // by `step` absolute.
    auto threshold = [&](double c, double s) {
      cv::Mat limit, mask;
      if (sign > 0) {
        const cv::Mat relative = background * (1 - c), absolute = background - s;
        cv::min(relative, absolute, limit);
        cv::compare(image, limit, mask, cv::CMP_LT);
      } else {
        const cv::Mat relative = background * (1 + c), absolute = background + s;
        cv::max(relative, absolute, limit);
        cv::compare(image, limit, mask, cv::CMP_GT);
      }
      return mask;
    };
    // Against the closed skin, hysteresis: a blob is seeded by pixels at
    // `contrast` and grown over the pixels at kGrowContrast of it, since
    // every pixel of a dot seen edge-on is only partly covered and few
    // reach the full contrast (a 4 px dot at view cosine 0.25 is a
    // pixel wide: one or two pixels pass, not a blob).
    // One pass gives the grown mask and the seeds.
    std::vector<cv::Point> seeds;
    cv::Mat mask;
    if (level == 2) {
      HysteresisMask(image, background, contrast, step, sign, &mask, &seeds);
    } else {
      mask = threshold(contrast, step);
    }
    cv::Mat labels, stats, centroids;
    const int n = cv::connectedComponentsWithStats(mask, labels, stats, centroids, 8, CV_32S);
    std::vector<char> seeded(n, level == 2 ? 0 : 1);
    for (const cv::Point &p : seeds) seeded[labels.at<int>(p)] = 1;
    const double min_area = std::max(2.0, M_PI / 4 * min_d * min_d / options.max_elongation);
    const double max_area = M_PI / 4 * max_d * max_d;
    const int border = options.border_px;
    for (int i = 1; i < n; ++i) {
      const int area = stats.at<int>(i, cv::CC_STAT_AREA);
      if (area < min_area || area > max_area || !seeded[i]) continue;
      const int left = stats.at<int>(i, cv::CC_STAT_LEFT), top = stats.at<int>(i, cv::CC_STAT_TOP);
      const int w = stats.at<int>(i, cv::CC_STAT_WIDTH), h = stats.at<int>(i, cv::CC_STAT_HEIGHT);
      const cv::Rect box(left, top, w, h);
      const BlobShape blob = MeasureBlob(labels, i, box, area);
      if (!PlausibleDot(blob, area, min_d, max_d, options)) continue;
      const BlobEllipse &shape = blob.ellipse;
      const double radius = blob.radius, major = blob.major;
      const double margin = border + shape.a + 4.5;
      const Vec2 start(centroids.at<double>(i, 0), centroids.at<double>(i, 1));
      if (start.x() < margin || start.y() < margin || start.x() + margin >= image.cols ||
          start.y() + margin >= image.rows) {
        continue;
      }
      // A dot the earlier levels found is found again here: skip it before
      // the (costly) centre refinement.
      if (level == 2 && std::any_of(out.begin(), out.begin() + earlier_count,
                                    [&](const DotDetection &d) {
                                      return (d.pixel - start).norm() < 0.5 * dot_size_px;
                                    })) {
        continue;
      }
      const Refined refined =
          RefineCentre(image, labels, i, start, shape, sign,
                       level == 2 ? kMaxRingIntrusionBesideDark : kMaxRingIntrusion);
      if (!refined.ok || refined.elongation > options.max_elongation) continue;
      if ((refined.centre - start).norm() > radius + 1) continue;
      const DotDetection dot = MakeDetection(refined, Vec2::Zero(), major);
      if (level > 0) {
        bool duplicate = false;
        for (size_t j = 0; j < earlier_count && !duplicate; ++j) {
          duplicate = (out[j].pixel - dot.pixel).norm() < 0.5 * dot_size_px;
        }
        if (duplicate) continue;
      }
      out.push_back(dot);
    }
  }
  std::sort(out.begin(), out.end(), [](const DotDetection &a, const DotDetection &b) {
    return a.pixel.y() != b.pixel.y() ? a.pixel.y() < b.pixel.y() : a.pixel.x() < b.pixel.x();
  });
  return out;
}

}  // namespace

std::vector<DotDetection> DetectDots(const cv::Mat &grey, const DotDetectorOptions &options,
                                     double dot_size_px) {
  return Detect(grey, options, dot_size_px, options.min_size * dot_size_px,
                options.max_size * dot_size_px);
}

namespace {

// The matched filter for an expected thin dot (docs/tracking.md,
// "Searching for an expected dot"): over a window round the prediction,
// the relative darkening against the closed skin, d = (S - I) / S, is
// modelled as a plane (the closing's bias over textured skin and what
// shading it leaves) plus A times the pixel coverage T of the predicted
// ellipse centred at the prediction + o:
//     d(x) = q0 + q1 dx + q2 dy + A T(x - o) + noise,
// A the paint's own relative darkening at full coverage. For each o on a
// grid over the search disc the four are fitted by least squares; the o
// of least squared residual is the maximum-likelihood centre (Gaussian
// residuals), refined on a finer grid. Its significance is A over its
// standard error, the residual's spread (skin texture and sensor noise
// together) taken from the fit itself: a likelihood-ratio test against
// "no dot here" that sees the whole ellipse, where a threshold on single
// pixels sees a thin dot's 1-3 partly covered pixels one at a time.
struct TemplateFit {
  bool ok = false;
  Vec2 centre = Vec2::Zero();  // patch coordinates (px)
  double contrast = 0;         // A
  double snr = 0;              // A / its standard error
  bool at_edge = false;        // the best centre on the search disc's rim
  // The darker of the strips beyond the ellipse's two ends, as a fraction
  // of the darkening along its middle (both above the fitted plane): a
  // dot ends where the ellipse does, a crease or a lid's edge goes on.
  double end_ratio = 0;
};

// Window pixels dark beyond this many robust sigmas of the window's skin
// outside the dot's reach are another dark thing (a neighbour's dot, a
// lid's or a lip's edge): left out of the fit, and counted per quarter.
constexpr double kTemplateOutlierSigmas = 4;
// The centre's grids (px): coarse over the search disc, then fine round
// the coarse optimum.
constexpr double kTemplateCoarseStep = 0.25;
constexpr double kTemplateFineStep = 0.05;
// Supersampling of the ellipse's pixel coverage (per axis): a 3 px dot at
// view cosine 0.15 is 0.45 px wide, and 8 samples resolve that to 1/8 px.
constexpr int kTemplateSamples = 8;

struct WindowPixel {
  double dx = 0, dy = 0;  // from the prediction (px)
  double d = 0;           // relative darkening against the closed skin
};

TemplateFit FitTemplate(const cv::Mat &image, const cv::Mat &skin, Vec2 at,
                        const BlobEllipse &shape, double radius, double sign,
                        double *max_intruded) {
  TemplateFit out;
  *max_intruded = 0;
  const double reach = shape.a + radius + kRingOut;
  int x0, x1, y0, y1;
  if (!ReachBox(image, at, reach, &x0, &x1, &y0, &y1)) return out;
  // The window: the ellipse grown by the search radius and the ring.
  std::vector<WindowPixel> all;
  std::vector<double> outside;  // d beyond the dot's reach (skin)
  for (int y = y0; y <= y1; ++y) {
    const float *row = image.ptr<float>(y);
    const float *b = skin.ptr<float>(y);
    for (int x = x0; x <= x1; ++x) {
      const double dx = x - at.x(), dy = y - at.y();
      if (!shape.Inside(dx, dy, radius + kRingOut) || !(b[x] > 1e-4f)) continue;
      const double d = sign * (b[x] - row[x]) / b[x];
      all.push_back({dx, dy, d});
      if (!shape.Inside(dx, dy, radius + 1)) outside.push_back(d);
    }
  }
  if (outside.size() < 16) return out;
  std::vector<double> sorted = outside;
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
  const double median = sorted[sorted.size() / 2];
  for (double &v : sorted) v = std::abs(v - median);
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
  const double spread = std::max(1e-4, 1.4826 * sorted[sorted.size() / 2]);
  // Dark intrusions beyond the dot's reach are left out, counted per
  // quarter (beyond either end, beside either side).
  std::vector<WindowPixel> window;
  int quarter_all[4] = {0, 0, 0, 0}, quarter_dark[4] = {0, 0, 0, 0};
  for (const WindowPixel &p : all) {
    if (shape.Inside(p.dx, p.dy, radius + 1)) {
      window.push_back(p);
      continue;
    }
    const double u = shape.ux * p.dx + shape.uy * p.dy, v = -shape.uy * p.dx + shape.ux * p.dy;
    const int q = std::abs(u) / shape.a > std::abs(v) / shape.b ? (u > 0 ? 0 : 1) : (v > 0 ? 2 : 3);
    ++quarter_all[q];
    if (p.d - median > kTemplateOutlierSigmas * spread) {
      ++quarter_dark[q];
    } else {
      window.push_back(p);
    }
  }
  for (int q = 0; q < 4; ++q) {
    if (quarter_all[q] == 0) return out;
    *max_intruded = std::max(*max_intruded, static_cast<double>(quarter_dark[q]) / quarter_all[q]);
  }
  const int n = static_cast<int>(window.size());
  // The plane's part of the normal equations is the same for every o.
  Eigen::Matrix3d pp = Eigen::Matrix3d::Zero();
  Eigen::Vector3d pd = Eigen::Vector3d::Zero();
  double dd = 0;
  for (const WindowPixel &p : window) {
    const Eigen::Vector3d x(1, p.dx, p.dy);
    pp += x * x.transpose();
    pd += x * p.d;
    dd += p.d * p.d;
  }
  const double inv = 1.0 / kTemplateSamples;
  // The fit at centre offset o: returns its squared residual; A, A's
  // variance factor ((X'X)^-1 at A) and the coefficients (q0, q1, q2, A).
  auto fit = [&](const Vec2 &o, double *a, double *a_var, Eigen::Vector4d *coefficients) {
    Eigen::Vector3d pt = Eigen::Vector3d::Zero();
    double tt = 0, td = 0;
    for (const WindowPixel &p : window) {
      const double cx = p.dx - o.x(), cy = p.dy - o.y();
      double coverage = 0;
      if (shape.Inside(cx - 0.5, cy - 0.5, 0) && shape.Inside(cx + 0.5, cy - 0.5, 0) &&
          shape.Inside(cx - 0.5, cy + 0.5, 0) && shape.Inside(cx + 0.5, cy + 0.5, 0)) {
        coverage = 1;  // the ellipse is convex: the whole pixel is inside
      } else if (shape.Inside(cx, cy, 0.75)) {  // a pixel's corner lies within 0.71 px of its centre
        int inside = 0;
        for (int sy = 0; sy < kTemplateSamples; ++sy) {
          for (int sx = 0; sx < kTemplateSamples; ++sx) {
            inside += shape.Inside(cx - 0.5 + (sx + 0.5) * inv, cy - 0.5 + (sy + 0.5) * inv, 0);
          }
        }
        coverage = inside * inv * inv;
      }
      if (coverage == 0) continue;
      pt += coverage * Eigen::Vector3d(1, p.dx, p.dy);
      tt += coverage * coverage;
      td += coverage * p.d;
    }
    Eigen::Matrix4d m;
    m.topLeftCorner<3, 3>() = pp;
    m.topRightCorner<3, 1>() = pt;
    m.bottomLeftCorner<1, 3>() = pt.transpose();
    m(3, 3) = tt;
    Eigen::Vector4d rhs;
    rhs << pd, td;
    const Eigen::LDLT<Eigen::Matrix4d> ldlt(m);
    const Eigen::Vector4d beta = ldlt.solve(rhs);
    if (!beta.allFinite() || !(tt > 0)) return std::numeric_limits<double>::infinity();
    *a = beta(3);
    *a_var = ldlt.solve(Eigen::Vector4d::UnitW())(3);
    *coefficients = beta;
    return dd - beta.dot(rhs);
  };
  double best = std::numeric_limits<double>::infinity(), best_a = 0, best_var = 0;
  Vec2 best_o = Vec2::Zero();
  Eigen::Vector4d best_beta = Eigen::Vector4d::Zero();
  auto consider = [&](const Vec2 &o) {
    double a = 0, var = 0;
    Eigen::Vector4d beta;
    const double sse = fit(o, &a, &var, &beta);
    // Only a darkening (A > 0) is a dot.
    if (a > 0 && sse < best) {
      best = sse;
      best_a = a;
      best_var = var;
      best_o = o;
      best_beta = beta;
    }
  };
  const int steps = static_cast<int>(std::floor(radius / kTemplateCoarseStep));
  for (int j = -steps; j <= steps; ++j) {
    for (int i = -steps; i <= steps; ++i) {
      const Vec2 o(i * kTemplateCoarseStep, j * kTemplateCoarseStep);
      if (o.norm() <= radius) consider(o);
    }
  }
  if (!std::isfinite(best)) return out;
  out.at_edge = best_o.norm() > radius - kTemplateCoarseStep;
  // The coarse optimum is within half a coarse step of the fine one.
  const Vec2 coarse = best_o;
  const int fine = static_cast<int>(std::ceil(0.5 * kTemplateCoarseStep / kTemplateFineStep));
  for (int j = -fine; j <= fine; ++j) {
    for (int i = -fine; i <= fine; ++i) {
      const Vec2 o = coarse + Vec2(i * kTemplateFineStep, j * kTemplateFineStep);
      if (o.norm() <= radius) consider(o);
    }
  }
  if (n <= 5 || !(best_var > 0)) return out;
  const double sigma2 = std::max(0.0, best) / (n - 4);
  // The darkening above the plane along the ellipse's middle and in the
  // strips 0.5-2.5 px beyond its ends (every window pixel, those left out
  // of the fit too), as wide as the ellipse and a pixel.
  double middle = 0, ends[2] = {0, 0};
  int n_middle = 0, n_ends[2] = {0, 0};
  for (const WindowPixel &p : all) {
    const double cx = p.dx - best_o.x(), cy = p.dy - best_o.y();
    const double u = shape.ux * cx + shape.uy * cy, v = -shape.uy * cx + shape.ux * cy;
    if (std::abs(v) > shape.b + 0.5) continue;
    const double above = p.d - (best_beta(0) + best_beta(1) * p.dx + best_beta(2) * p.dy);
    if (std::abs(u) <= std::max(0.5, shape.a - 0.5)) {
      middle += above;
      ++n_middle;
    } else if (std::abs(u) > shape.a + 0.5 && std::abs(u) <= shape.a + 2.5) {
      ends[u > 0] += above;
      ++n_ends[u > 0];
    }
  }
  if (n_middle == 0 || n_ends[0] == 0 || n_ends[1] == 0 || !(middle > 0)) return out;
  out.end_ratio = std::max(ends[0] / n_ends[0], ends[1] / n_ends[1]) / (middle / n_middle);
  out.ok = true;
  out.centre = at + best_o;
  out.contrast = best_a;
  out.snr = best_a / std::sqrt(std::max(1e-12, sigma2 * best_var));
  return out;
}

// The patch of the frame round an expected dot: the search disc, the
// largest dot, its ring and the closing's reach; as floats, with the skin
// without the dots (the closing) and the prediction in its coordinates.
struct ExpectedPatch {
  cv::Rect rect;
  cv::Mat image, skin;
  Vec2 at = Vec2::Zero();
};

std::optional<ExpectedPatch> MakeExpectedPatch(const cv::Mat &grey,
                                               const DotDetectorOptions &options,
                                               double dot_size_px, const ExpectedDot &expected,
                                               double sign) {
  const int half = static_cast<int>(std::ceil(expected.radius_px +
                                              0.5 * options.max_size * dot_size_px + kRingOut +
                                              2 + ClosingSide(dot_size_px)));
  ExpectedPatch out;
  out.rect = cv::Rect(static_cast<int>(std::lround(expected.pixel.x())) - half,
                      static_cast<int>(std::lround(expected.pixel.y())) - half, 2 * half + 1,
                      2 * half + 1);
  const cv::Rect &rect = out.rect;
  const int border = options.border_px;
  if (rect.x < border || rect.y < border || rect.x + rect.width > grey.cols - border ||
      rect.y + rect.height > grey.rows - border) {
    return std::nullopt;
  }
  const cv::Mat patch = grey(rect);
  out.image = AsFloat(patch);
  if (out.image.data == patch.data) out.image = out.image.clone();
  out.skin = ClosedSkin(patch, dot_size_px, sign);
  out.at = expected.pixel - Vec2(rect.x, rect.y);
  return out;
}

// The matched filter of the predicted ellipse (long axis the dot's
// diameter across the projected normal, short axis times the view cosine)
// within `radius` of the prediction, taken where it is significant
// against the window's own texture, of a paint's darkening, its optimum
// inside the search disc, and the window's skin not cut by a dark edge.
std::optional<DotDetection> AcceptedTemplate(const ExpectedPatch &patch,
                                             const DotDetectorOptions &options,
                                             double dot_size_px, const ExpectedDot &expected,
                                             double radius, double sign) {
  BlobEllipse shape;
  shape.a = 0.5 * dot_size_px;
  shape.b = shape.a * std::clamp(expected.axis_ratio, 1 / options.max_elongation, 1.0);
  shape.ux = -expected.short_axis.y();
  shape.uy = expected.short_axis.x();
  double intruded = 0;
  const TemplateFit fit =
      FitTemplate(patch.image, patch.skin, patch.at, shape, radius, sign, &intruded);
  if (!fit.ok || fit.at_edge || fit.snr < kTemplateMinSnr) return std::nullopt;
  if (fit.end_ratio > kTemplateMaxEndRatio) return std::nullopt;
  if (fit.contrast < options.min_contrast || fit.contrast > kTemplateMaxContrast) {
    return std::nullopt;
  }
  if (intruded > kMaxRingIntrusion) return std::nullopt;
  Refined refined;
  refined.ok = true;
  refined.centre = fit.centre;
  refined.contrast = fit.contrast;
  refined.elongation = shape.a / shape.b;
  return MakeDetection(refined, Vec2(patch.rect.x, patch.rect.y), 2 * shape.a);
}

}  // namespace

std::optional<DotDetection> DetectDotNear(const cv::Mat &grey, const DotDetectorOptions &options,
                                          double dot_size_px, const ExpectedDot &expected) {
  const double sign = options.polarity == "bright" ? -1 : 1;
  const std::optional<ExpectedPatch> patch =
      MakeExpectedPatch(grey, options, dot_size_px, expected, sign);
  if (!patch) return std::nullopt;
  const cv::Rect &rect = patch->rect;
  const cv::Mat &image = patch->image, &skin = patch->skin;
  const Vec2 &at = patch->at;
  const double noise = EstimateNoise(image, 1);
  bool ambiguous = false;
  auto blob_search = [&]() -> std::optional<DotDetection> {
    // Seeds at kGuidedContrast of the blind levels' contrast and noise
    // margin, grown as at the closed-skin level.
    const double step = kGuidedContrast * std::max(options.min_step, kNoiseSigmas * noise);
    cv::Mat mask;
    std::vector<cv::Point> seeds;
    HysteresisMask(image, skin, kGuidedContrast * options.min_contrast, step, sign, &mask, &seeds);
    cv::Mat labels, stats, centroids;
    const int n = cv::connectedComponentsWithStats(mask, labels, stats, centroids, 8, CV_32S);
    std::vector<char> seeded(n, 0);
    for (const cv::Point &p : seeds) seeded[labels.at<int>(p)] = 1;
    const double min_d = options.min_size * dot_size_px, max_d = options.max_size * dot_size_px;
    int found = -1;
    BlobShape found_shape;
    for (int i = 1; i < n; ++i) {
      const Vec2 centroid(centroids.at<double>(i, 0), centroids.at<double>(i, 1));
      if ((centroid - at).norm() > expected.radius_px) continue;
      const int area = stats.at<int>(i, cv::CC_STAT_AREA);
      if (area < 2 || area > M_PI / 4 * max_d * max_d || !seeded[i]) continue;
      const cv::Rect box(stats.at<int>(i, cv::CC_STAT_LEFT), stats.at<int>(i, cv::CC_STAT_TOP),
                         stats.at<int>(i, cv::CC_STAT_WIDTH), stats.at<int>(i, cv::CC_STAT_HEIGHT));
      const BlobShape shape = MeasureBlob(labels, i, box, area);
      if (!PlausibleDot(shape, area, min_d, std::min(max_d, kGuidedMaxLength * dot_size_px),
                        options)) {
        continue;
      }
      // Two dark blobs where one dot is expected: not told apart here.
      if (found >= 0) {
        ambiguous = true;
        return std::optional<DotDetection>();
      }
      found = i;
      found_shape = shape;
    }
    if (found < 0) return std::optional<DotDetection>();
    const Refined refined = RefineCentre(image, labels, found, found_shape.centre,
                                         found_shape.ellipse, sign, kMaxRingIntrusionBesideDark);
    if (!refined.ok || refined.elongation > options.max_elongation ||
        (refined.centre - found_shape.centre).norm() > found_shape.radius + 1 ||
        (refined.centre - at).norm() > expected.radius_px) {
      return std::optional<DotDetection>();
    }
    // A thin dot lies across its projected normal: a dark streak along it
    // (a crease, a lash, a lid's edge) is not the dot.
    if (expected.axis_ratio < kGuidedOrientedRatio &&
        refined.elongation > 1 / kGuidedOrientedRatio) {
      const double along = std::abs(found_shape.ellipse.ux * expected.short_axis.x() +
                                    found_shape.ellipse.uy * expected.short_axis.y());
      if (along > kGuidedMaxAxisSine) return std::optional<DotDetection>();
    }
    return MakeDetection(refined, Vec2(rect.x, rect.y), found_shape.major);
};
  if (std::optional<DotDetection> dot = blob_search()) return dot;
  if (ambiguous) return std::nullopt;
  // No blob: the dot too faint or too thin for a threshold on its pixels
  // (a 3 px dot at view cosine 0.2 is under a pixel wide), or blurred and
  // faint (the hard preset), or joined to a dark edge (a lid, a lip) into
  // a blob the blob tests refuse: the matched filter of its predicted
  // ellipse (FitTemplate), whose plane, left-out dark pixels and test of
  // the strips beyond its ends keep an edge from being taken for the dot.
  return AcceptedTemplate(*patch, options, dot_size_px, expected,
                          std::min(expected.radius_px, kTemplateMaxOffset), sign);
}

double MeasureDotSize(const cv::Mat &grey, const DotDetectorOptions &options) {
  const std::vector<DotDetection> all = Detect(grey, options, 8.0, 1.6, 16.0);
  std::vector<double> sizes;
  for (const DotDetection &d : all) {
    if (d.elongation < 1.4 && d.contrast > 1.5 * options.min_contrast)
      sizes.push_back(d.diameter_px);
  }
  if (sizes.size() < 8) return 0;
  std::nth_element(sizes.begin(), sizes.begin() + sizes.size() / 2, sizes.end());
  return sizes[sizes.size() / 2];
}

}  // namespace hmc
