#include "tracking/dot_detector.h"

#include <algorithm>
#include <cmath>
#include <random>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

namespace hmc {
namespace {

// Skin with a shading gradient and noise; dark discs at random sub-pixel
// centres, anti-aliased by 8 x 8 supersampling (their centroid is the
// disc's centre up to the supersampling, < 0.005 px).
struct Scene {
  cv::Mat image;  // CV_8U
  std::vector<Vec2> centres;
};

// Multiplies `radiance` by the paint (radiance 0.07 on skin of 0.6) over a
// disc of diameter `diameter` centred at `c`, seen at view cosine `cos`:
// an ellipse of axes diameter and cos x diameter, its long axis at `angle`
// (its area centroid is still its centre), anti-aliased by 8 x 8
// supersampling.
void PaintDot(cv::Mat* radiance, const Vec2& c, double diameter, double cos, double angle) {
  const double r = diameter / 2;
  const double ca = std::cos(angle), sa = std::sin(angle);
  for (int y = static_cast<int>(c.y() - r - 2); y <= c.y() + r + 2; ++y) {
    for (int x = static_cast<int>(c.x() - r - 2); x <= c.x() + r + 2; ++x) {
      int inside = 0;
      for (int sy = 0; sy < 8; ++sy) {
        for (int sx = 0; sx < 8; ++sx) {
          const double px = x - 0.5 + (sx + 0.5) / 8 - c.x(), py = y - 0.5 + (sy + 0.5) / 8 - c.y();
          const double along = ca * px + sa * py, across = (-sa * px + ca * py) / cos;
          inside += std::hypot(along, across) <= r;
        }
      }
      const double coverage = inside / 64.0;
      radiance->at<double>(y, x) *= 1 - coverage * (1 - 0.07 / 0.6);
    }
  }
}

// Shaded skin (radiance about 0.6) whose albedo varies by +-texture
// (uniform per pixel, as a rough stand-in for pores and freckles).
cv::Mat MakeSkin(std::mt19937* rng, int w, int h, double texture) {
  std::uniform_real_distribution<double> u01(0, 1);
  cv::Mat radiance(h, w, CV_64F);
  const double gx = 0.3 * (u01(*rng) - 0.5) / w, gy = 0.3 * (u01(*rng) - 0.5) / h;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      radiance.at<double>(y, x) = (0.6 + gx * (x - w / 2) + gy * (y - h / 2)) *
                                  (1 + texture * (2 * u01(*rng) - 1));
    }
  }
  return radiance;
}

// The 8-bit image of `radiance` with read noise of sigma `noise`.
cv::Mat Expose(const cv::Mat& radiance, double noise, std::mt19937* rng) {
  std::normal_distribution<double> normal(0, 1);
  cv::Mat image(radiance.rows, radiance.cols, CV_8U);
  for (int y = 0; y < radiance.rows; ++y) {
    for (int x = 0; x < radiance.cols; ++x) {
      const double v = 255 * radiance.at<double>(y, x) + noise * normal(*rng);
      image.at<uint8_t>(y, x) = cv::saturate_cast<uint8_t>(std::lround(v));
    }
  }
  return image;
}

// `cos` < 1: each disc seen at that view cosine at a random orientation.
Scene MakeScene(int seed, double diameter, int count, double noise, double cos = 1,
                double texture = 0) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u01(0, 1);
  const int w = 480, h = 360;
  cv::Mat radiance = MakeSkin(&rng, w, h, texture);
  Scene scene;
  const double spacing = std::max(4 * diameter, 24.0);
  for (double y = spacing; y < h - spacing && static_cast<int>(scene.centres.size()) < count; y += spacing) {
    for (double x = spacing; x < w - spacing && static_cast<int>(scene.centres.size()) < count; x += spacing) {
      scene.centres.emplace_back(x + u01(rng) - 0.5, y + u01(rng) - 0.5);
    }
  }
  for (const Vec2& c : scene.centres) {
    PaintDot(&radiance, c, diameter, cos, cos < 1 ? M_PI * u01(rng) : 0);
  }
  scene.image = Expose(radiance, noise, &rng);
  return scene;
}

// Every dot found within 1 px, nothing else found, and the centres within
// the targets for dots seen edge-on (docs/tracking.md: median
// 0.05 px, p95 0.2 px).
void ExpectEachFoundAndCentred(const std::vector<Vec2>& centres,
                               const std::vector<DotDetection>& found, const std::string& what) {
  std::vector<double> errors;
  int missed = 0;
  for (const Vec2& c : centres) {
    double best = 1e9;
    for (const DotDetection& d : found) best = std::min(best, (d.pixel - c).norm());
    if (best > 1) {
      ++missed;
    } else {
      errors.push_back(best);
    }
  }
  EXPECT_EQ(missed, 0) << what;
  EXPECT_EQ(found.size(), centres.size()) << what;
  ASSERT_FALSE(errors.empty()) << what;
  std::sort(errors.begin(), errors.end());
  EXPECT_LT(errors[errors.size() / 2], 0.05) << what;
  EXPECT_LT(errors[errors.size() * 95 / 100], 0.2) << what;
}

TEST(DotDetectorTest, CentresAreSubPixelAccurateOnShadedNoisySkin) {
  DotDetectorOptions options;
  for (int seed = 1; seed <= 4; ++seed) {
    for (double diameter : {3.0, 6.0, 11.0}) {
      const Scene scene = MakeScene(seed, diameter, 40, 1.0);
      const std::vector<DotDetection> found = DetectDots(scene.image, options, diameter);
      EXPECT_EQ(found.size(), scene.centres.size()) << "seed " << seed << " d " << diameter;
      std::vector<double> errors;
      for (const Vec2& c : scene.centres) {
        double best = 1e9;
        for (const DotDetection& d : found) best = std::min(best, (d.pixel - c).norm());
        errors.push_back(best);
      }
      std::sort(errors.begin(), errors.end());
      // 8-bit quantisation and read noise 1 on 3 to 11 px discs; the issue's
      // targets for full dots (median 0.05 px, p95 0.15 px).
      EXPECT_LT(errors[errors.size() / 2], 0.05) << "seed " << seed << " d " << diameter;
      EXPECT_LT(errors[errors.size() * 95 / 100], 0.15) << "seed " << seed << " d " << diameter;
    }
  }
}

// Dots seen edge-on (issue 44): ellipses of 3.3:1 to 5:1 (view cosine
// 0.3 down to 0.2) at random sub-pixel centres and orientations, on
// textured, shaded, noisy skin; each is found and centred on its area
// centroid (docs/tracking.md targets: median 0.05 px, p95 0.2 px).
TEST(DotDetectorTest, CentresEdgeOnEllipsesAtSubPixelPositions) {
  DotDetectorOptions options;
  for (int seed = 1; seed <= 3; ++seed) {
    // cos 0.15 (6.7:1) is the target but not met yet on 6 px
    // ellipses (0.9 px wide): 1 of 40 missed per seed, median up to
    // 0.062 px; the 9 and 12 px ones pass (docs/tracking.md).
    for (double cos : {0.2, 0.25, 0.3}) {
      for (double diameter : {6.0, 9.0, 12.0}) {
        const Scene scene = MakeScene(10 * seed, diameter, 40, 1.0, cos, 0.05);
        ExpectEachFoundAndCentred(scene.centres, DetectDots(scene.image, options, diameter),
                                  fmt::format("seed {} cos {} d {}", seed, cos, diameter));
      }
    }
  }
}

// Dots seen edge-on beside a dark region (issue 44: the dark beyond a
// silhouette, a shadowed lid, an eyebrow): a thin ellipse (view cosine
// 0.25-0.3, its long axis near vertical) whose left side faces, `gap` px
// from its centre, the edge of a dark band (radiance x 0.05, 2 dot
// diameters wide, the image's height long) on textured, shaded, noisy
// skin. Each dot is found and centred (docs/tracking.md targets: median
// 0.05 px, p95 0.2 px), and the band's edge, which the detector's level
// against the closed skin sees as darker than the skin, yields no dot.
// At cos 0.2 and for dots under 6 px the blind detector still misses some
// (docs/tracking.md).
TEST(DotDetectorTest, FindsEdgeOnDotsBesideADarkRegionAndNoneAtItsEdge) {
  DotDetectorOptions options;
  for (int seed = 1; seed <= 3; ++seed) {
    for (double cos : {0.25, 0.3}) {
      for (double diameter : {6.0, 9.0}) {
        std::mt19937 rng(1000 * seed + static_cast<int>(100 * cos) + static_cast<int>(diameter));
        std::uniform_real_distribution<double> u01(0, 1);
        const int w = 480, h = 360;
        cv::Mat radiance = MakeSkin(&rng, w, h, 0.05);
        const double gap = 4, spacing = 48;
        std::vector<Vec2> centres;
        for (double x = spacing; x < w - spacing; x += spacing) {
          // The band's edge at x - gap, anti-aliased (its coverage).
          for (int px = static_cast<int>(x - gap - 2 * diameter) - 1; px <= x - gap + 1; ++px) {
            const double coverage = std::clamp(std::min(x - gap - (px - 0.5),
                                                        px + 0.5 - (x - gap - 2 * diameter)),
                                               0.0, 1.0);
            for (int y = 0; y < h; ++y) radiance.at<double>(y, px) *= 1 - 0.95 * coverage;
          }
          for (double y = spacing; y < h - spacing; y += spacing) {
            const Vec2 c(x + u01(rng) - 0.5, y + u01(rng) - 0.5);
            centres.push_back(c);
            PaintDot(&radiance, c, diameter, cos, M_PI / 2 + 0.4 * (u01(rng) - 0.5));
          }
        }
        const cv::Mat image = Expose(radiance, 1.0, &rng);
        ExpectEachFoundAndCentred(centres, DetectDots(image, options, diameter),
                                  fmt::format("seed {} cos {} d {}", seed, cos, diameter));
      }
    }
  }
}

// The search for an expected dot (issue 44: dots seen edge-on and small):
// thin ellipses the blind detector loses (3-4 px dots at view cosine 0.15
// to 0.3, under a pixel wide) on textured, shaded, noisy skin, each
// searched for from a prediction up to 0.5 px off its centre with the
// ellipse its normal predicts. Most are found and centred on their area
// centroid; a search where no dot is painted finds nothing, also where a
// crease runs along the predicted ellipse.
TEST(DotDetectorTest, FindsExpectedThinDotsAndNothingOnBareSkin) {
  DotDetectorOptions options;
  for (int seed = 1; seed <= 3; ++seed) {
    for (double cos : {0.15, 0.2, 0.3}) {
      for (double diameter : {3.0, 4.0}) {
        std::mt19937 rng(7000 + 100 * seed + static_cast<int>(100 * cos) +
                         static_cast<int>(diameter));
        std::uniform_real_distribution<double> u01(0, 1);
        const int w = 480, h = 360;
        cv::Mat radiance = MakeSkin(&rng, w, h, 0.05);
        const double spacing = 24;
        std::vector<Vec2> centres, short_axes, bare;
        int i = 0;
        for (double y = 2 * spacing; y < h - 2 * spacing; y += spacing) {
          for (double x = 2 * spacing; x < w - 2 * spacing; x += spacing, ++i) {
            const Vec2 c(x + u01(rng) - 0.5, y + u01(rng) - 0.5);
            const double angle = M_PI * u01(rng);
            if (i % 4 == 3) {  // every fourth place: bare skin
              bare.push_back(c);
              short_axes.emplace_back(-std::sin(angle), std::cos(angle));
              // Every other one crossed by a crease along the predicted
              // ellipse: a dark line five dots long and a pixel wide.
              if (bare.size() % 2 == 0) {
                PaintDot(&radiance, c, 5 * diameter, 1 / (5 * diameter), angle);
              }
              continue;
            }
            PaintDot(&radiance, c, diameter, cos, angle);
            centres.push_back(c);
            short_axes.emplace_back(-std::sin(angle), std::cos(angle));
          }
        }
        const cv::Mat image = Expose(radiance, 1.0, &rng);
        const std::string what = fmt::format("seed {} cos {} d {}", seed, cos, diameter);
        auto expect = [&](const Vec2& c, const Vec2& short_axis) {
          ExpectedDot e;
          const double r = 0.5 * u01(rng), a = 2 * M_PI * u01(rng);
          e.pixel = c + r * Vec2(std::cos(a), std::sin(a));
          e.radius_px = 0.3 * spacing;
          e.axis_ratio = cos;
          e.short_axis = short_axis;
          return DetectDotNear(image, options, diameter, e);
        };
        std::vector<double> errors;
        size_t k = 0, b = 0;
        i = 0;
        for (double y = 2 * spacing; y < h - 2 * spacing; y += spacing) {
          for (double x = 2 * spacing; x < w - 2 * spacing; x += spacing, ++i) {
            if (i % 4 == 3) {
              EXPECT_FALSE(expect(bare[b], short_axes[i]).has_value()) << what << " bare " << b;
              ++b;
              continue;
            }
            const std::optional<DotDetection> found = expect(centres[k], short_axes[i]);
            if (found) errors.push_back((found->pixel - centres[k]).norm());
            ++k;
          }
        }
        // By the ellipse's width (measured, docs/tracking.md; the matched
        // filter of the predicted ellipse finds what no threshold does):
        // 0.45 px (3 px at cos 0.15) 98-99 % found (43-57 % by the centroid
        // over the ellipse it replaced), median 0.08-0.11 px, p95 0.28-0.39
        // px; 0.6 px 99-100 %, median 0.05-0.07, p95 0.24-0.27; from 0.8 px
        // 99-100 %, median 0.03-0.05, p95 0.08-0.15.
        std::sort(errors.begin(), errors.end());
        const double width = diameter * cos;
        // The thinnest dots' p95 bound is 0.4 px over 95 % of the dots; the
        // centroid it replaced was held to 0.35 px over the 40 % it found,
        // which the median bound over 95 % (0.12 px) now implies.
        const double least = 0.95;
        const double median = width < 0.5 ? 0.12 : width < 0.7 ? 0.08 : 0.06;
        const double p95 = width < 0.5 ? 0.4 : width < 0.7 ? 0.3 : 0.2;
        EXPECT_GE(errors.size(), least * centres.size()) << what;
        ASSERT_FALSE(errors.empty()) << what;
        EXPECT_LT(errors[errors.size() / 2], median) << what;
        EXPECT_LT(errors[errors.size() * 95 / 100], p95) << what;
      }
    }
  }
}

TEST(DotDetectorTest, SizeIsMeasuredAndNonDotsAreRejected) {
  DotDetectorOptions options;
  for (int seed = 1; seed <= 3; ++seed) {
    const double diameter = 4 + 2 * seed;
    Scene scene = MakeScene(seed, diameter, 20, 1.0);
    EXPECT_NEAR(MeasureDotSize(scene.image, options), diameter, 0.2 * diameter);
    // A long dark line (a lip line, a lash) and a big dark blob (a nostril).
    cv::line(scene.image, cv::Point(10, 5), cv::Point(470, 8), cv::Scalar(15), 2);
    cv::circle(scene.image, cv::Point(240, 352), 0, cv::Scalar(15), -1);
    cv::ellipse(scene.image, cv::Point(460, 340), cv::Size(12, 12), 0, 0, 360, cv::Scalar(10), -1);
    const std::vector<DotDetection> found = DetectDots(scene.image, options, diameter);
    EXPECT_EQ(found.size(), scene.centres.size()) << "seed " << seed;
    for (const DotDetection& d : found) {
      EXPECT_GT(d.pixel.y(), 12);
      EXPECT_GE(d.score, 0);
      EXPECT_LE(d.score, 1);
    }
  }
}

TEST(DotDetectorTest, BrightDotsWithBrightPolarity) {
  Scene scene = MakeScene(7, 6, 20, 1.0);
  cv::Mat inverted = 255 - scene.image;
  DotDetectorOptions options;
  options.polarity = "bright";
  EXPECT_EQ(DetectDots(inverted, options, 6).size(), scene.centres.size());
  options.polarity = "dark";
  EXPECT_EQ(DetectDots(inverted, options, 6).size(), 0u);
}

}  // namespace
}  // namespace hmc
