#include "tracking/track_eval.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <tuple>

#include <fmt/format.h>

namespace hmc {

std::string TrackScore::BriefReport() const {
  const std::string half =
      partial_half > 0 ? fmt::format(" (at least half seen: {:.2f} % of {})",
                                     100 * PartialHalfRecall(), partial_half)
                       : std::string();
  return fmt::format(
      "full: median {:.4f} px, p95 {:.4f} px, max {:.3f} px, named {:.2f} % of {}; partial "
      "named {:.2f} % of {}{}; wrong names {} of {} rows ({:.3f} %: {} nearer another marker's "
      "dot, {} only more than 2 px off their own); rows on hidden dots {} of {} ({:.2f} %)",
      median_px, p95_px, max_px, 100 * FullRecall(), full, 100 * PartialRecall(), partial, half,
      wrong, rows, 100 * WrongFraction(), wrong_other, wrong_off, hidden_rows, hidden,
      100 * HiddenFraction());
}

std::string CosBinName(int bin) {
  return bin + 1 < kNumCosBins ? fmt::format("{:g}-{:g}", kCosBins[bin], kCosBins[bin + 1])
                               : fmt::format(">={:g}", kCosBins[bin]);
}

std::string TrackScore::WholeReport() const {
  if (!has_whole) return std::string();
  std::string out = "whole dots by view cosine:";
  auto one = [](const WholeDotBin& b) {
    return fmt::format("named {:.2f} % of {}, median {:.4f} px, p95 {:.4f} px", 100 * b.Recall(),
                       b.views, b.median_px, b.p95_px);
  };
  for (int i = 0; i < kNumCosBins; ++i) {
    out += fmt::format(" [{}] {};", CosBinName(i), one(whole_bins[i]));
  }
  out += fmt::format(" [>=0.15] {}", one(whole_from_015));
  return out;
}

namespace {

double Quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const double pos = q * (v.size() - 1);
  const size_t i = static_cast<size_t>(std::floor(pos));
  const double t = pos - i;
  return i + 1 < v.size() ? (1 - t) * v[i] + t * v[i + 1] : v[i];
}

}  // namespace

TrackScore ScoreTracks(const std::vector<Track2d>& tracks, const std::vector<Dot2dTruth>& truth,
                       double wrong_px) {
  TrackScore score;
  int first = std::numeric_limits<int>::max();
  std::map<std::tuple<int, std::string, std::string>, const Track2d*> by_key;
  for (const Track2d& t : tracks) {
    first = std::min(first, t.frame);
    by_key[{t.frame, t.camera, t.marker}] = &t;
  }
  std::map<std::tuple<int, std::string, std::string>, const Dot2dTruth*> truth_by_key;
  std::map<std::pair<int, std::string>, std::vector<const Dot2dTruth*>> visible_by_view;
  for (const Dot2dTruth& d : truth) {
    truth_by_key[{d.frame, d.camera, d.marker}] = &d;
    if (d.visible) visible_by_view[{d.frame, d.camera}].push_back(&d);
  }
  std::vector<double> errors;
  std::vector<double> whole_errors[kNumCosBins], whole_from_015_errors;
  for (const Dot2dTruth& d : truth) {
    if (d.frame < first) continue;
    auto it = by_key.find({d.frame, d.camera, d.marker});
    const bool named = it != by_key.end();
    if (d.whole >= 0) score.has_whole = true;
    if (d.whole == 1 && d.has_cos && d.has_whole_centroid) {
      int bin = 0;
      while (bin + 1 < kNumCosBins && d.view_cos >= kCosBins[bin + 1]) ++bin;
      const bool edge_015 = d.view_cos >= kCosBins[1];
      ++score.whole_bins[bin].views;
      score.whole_from_015.views += edge_015;
      if (named) {
        const double e = (it->second->pixel - d.whole_centroid).norm();
        ++score.whole_bins[bin].named;
        whole_errors[bin].push_back(e);
        if (edge_015) {
          ++score.whole_from_015.named;
          whole_from_015_errors.push_back(e);
        }
      }
    }
    switch (d.disc) {
      case DotDiscState::kFull:
        ++score.full;
        if (named) {
          ++score.full_named;
          errors.push_back((it->second->pixel - d.centroid).norm());
          score.full_errors_by_frame[d.frame].push_back(errors.back());
        }
        break;
      case DotDiscState::kPartial:
        ++score.partial;
        score.partial_named += named;
        if (d.seen >= 0.5) {
          ++score.partial_half;
          score.partial_half_named += named;
        }
        break;
      case DotDiscState::kHidden:
        ++score.hidden;
        score.hidden_rows += named;
        break;
    }
  }
  for (const Track2d& t : tracks) {
    ++score.rows;
    auto it = truth_by_key.find({t.frame, t.camera, t.marker});
    if (it == truth_by_key.end()) {
      ++score.wrong;
      ++score.wrong_other;  // a marker the truth does not place here
      continue;
    }
    const Dot2dTruth& own = *it->second;
    const Vec2 own_centre = own.has_centroid         ? own.centroid
                            : own.has_whole_centroid ? own.whole_centroid
                                                     : own.pixel;
    const bool off = (t.pixel - own_centre).norm() > wrong_px;
    bool other = false;
    const double own_point_d = (t.pixel - own.pixel).norm();
    for (const Dot2dTruth* o : visible_by_view[{t.frame, t.camera}]) {
      if (o->marker != t.marker && (t.pixel - o->pixel).norm() < own_point_d) other = true;
    }
    score.wrong += off || other;
    score.wrong_other += other;
    score.wrong_off += off && !other;
  }
  for (int i = 0; i < kNumCosBins; ++i) {
    score.whole_bins[i].median_px = Quantile(whole_errors[i], 0.5);
    score.whole_bins[i].p95_px = Quantile(whole_errors[i], 0.95);
  }
  score.whole_from_015.median_px = Quantile(whole_from_015_errors, 0.5);
  score.whole_from_015.p95_px = Quantile(whole_from_015_errors, 0.95);
  score.median_px = Quantile(errors, 0.5);
  score.p95_px = Quantile(errors, 0.95);
  score.max_px = errors.empty() ? 0 : *std::max_element(errors.begin(), errors.end());
  return score;
}

}  // namespace hmc
