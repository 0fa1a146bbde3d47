#include "synth/truth_frames.h"

#include <algorithm>
#include <cmath>

#include <spdlog/spdlog.h>

#include "core/error.h"
#include "core/logging.h"
#include "core/parallel.h"
#include "synth/face_mesh.h"
#include "synth/synth_random.h"

namespace hmc {

void TruthFramesOptions::Register(OptionFields* fields) {
  fields->Add("kind", &kind, "dataset | combos | performance");
  fields->Add("frames", &frames, "number of frames (combos, performance)");
  fields->Add("seed", &seed, "random seed of the activations and the bundle noise");
  fields->Add("noise_mm", &noise_mm, "std of Gaussian noise per bundle coordinate (mm)");
  fields->Add("fps", &fps, "frame rate (frames per second)");
  fields->Add("min_units", &min_units, "combos: fewest units active per frame");
  fields->Add("max_units", &max_units, "combos: most units active per frame");
  fields->Add("min_activation", &min_activation, "combos: activations drawn in [min, 1]");
}

bool TruthFramesOptions::Check() const {
  bool ok = true;
  auto fail = [&](const std::string& message) {
    spdlog::error("actor frames options: {}", message);
    ok = false;
  };
  if (kind != "dataset" && kind != "combos" && kind != "performance") {
    fail("kind must be dataset, combos or performance, got '" + kind + "'");
  }
  if (frames < 1 || frames > 100000) fail("frames must be in [1, 100000]");
  if (!(noise_mm >= 0 && noise_mm <= 50)) fail("noise_mm must be in [0, 50]");
  if (!(fps > 0 && fps <= 1000)) fail("fps must be in (0, 1000]");
  if (min_units < 1 || max_units < min_units) fail("need 1 <= min_units <= max_units");
  if (!(min_activation > 0 && min_activation <= 1)) fail("min_activation must be in (0, 1]");
  return ok;
}

namespace {

// Random combinations of min..max distinct units at fresh activations.
std::vector<Eigen::VectorXd> Combos(const FaceModel& model,
                                    const std::vector<DatasetEntry>& plan,
                                    const TruthFramesOptions& options) {
  SynthRandom rng = SynthRandom::Stream(static_cast<uint64_t>(options.seed), 10);
  const int num_units = model.NumUnits();
  const int max_units = std::min(options.max_units, num_units);
  const int min_units = std::min(options.min_units, max_units);
  std::vector<Eigen::VectorXd> out;
  while (static_cast<int>(out.size()) < options.frames) {
    Eigen::VectorXd a = model.ZeroActivations();
    const int count = min_units + rng.Index(max_units - min_units + 1);
    for (int placed = 0; placed < count;) {
      const int k = rng.Index(num_units);
      if (a[k] != 0) continue;
      a[k] = rng.Uniform(options.min_activation, 1.0);
      ++placed;
    }
    const bool in_dataset = std::any_of(plan.begin(), plan.end(), [&](const DatasetEntry& e) {
      return e.activations == a;
    });
    if (!in_dataset) out.push_back(std::move(a));
  }
  return out;
}

// An envelope: rises over `attack` s from `start`, holds, releases; smooth.
double Envelope(double t, double start, double attack, double hold,
                double release) {
  if (t <= start || t >= start + attack + hold + release) return 0.0;
  if (t < start + attack) return SmoothStep(start, start + attack, t);
  if (t < start + attack + hold) return 1.0;
  return 1.0 - SmoothStep(start + attack + hold, start + attack + hold + release, t);
}

// A performance: expression events (onset, hold, release) on random units,
// stretches of speech-like jaw and lip motion, blinks every few seconds.
std::vector<Eigen::VectorXd> Performance(const FaceModel& model,
                                         const TruthFramesOptions& options) {
  SynthRandom rng = SynthRandom::Stream(static_cast<uint64_t>(options.seed), 11);
  const int num_units = model.NumUnits();
  const double duration = options.frames / options.fps;
  struct Event {
    int unit;
    double start, attack, hold, release, peak;
  };
  std::vector<Event> events;
  // About one expression event per second, on non-jaw units.
  std::vector<int> expression_units;
  for (int k = 0; k < num_units; ++k) {
    if (!model.units()[k].drives_jaw) expression_units.push_back(k);
  }
  const int num_events = std::max(1, static_cast<int>(std::ceil(duration)));
  for (int e = 0; e < num_events; ++e) {
    Event event;
    event.unit = expression_units[rng.Index(static_cast<int>(expression_units.size()))];
    event.start = rng.Uniform(-0.5, duration);
    event.attack = rng.Uniform(0.25, 0.6);
    event.hold = rng.Uniform(0.2, 1.2);
    event.release = rng.Uniform(0.25, 0.7);
    event.peak = rng.Uniform(0.3, 1.0);
    events.push_back(event);
  }
  // Speech: stretches with the jaw and lips moving at syllable rate.
  struct Speech {
    double start, length, rate_hz, phase;
  };
  std::vector<Speech> speech;
  for (double t = rng.Uniform(0.0, 0.8); t < duration; t += rng.Uniform(1.5, 3.5)) {
    speech.push_back({t, rng.Uniform(0.8, 2.0), rng.Uniform(3.0, 5.0),
                      rng.Uniform(0.0, 2 * M_PI)});
  }
  // Blinks every 2-5 s, both eyes, ~0.3 s.
  std::vector<double> blinks;
  for (double t = rng.Uniform(0.3, 2.0); t < duration; t += rng.Uniform(2.0, 5.0)) {
    blinks.push_back(t);
  }
  const int jaw_drop = model.FindUnit("AU26_jaw_drop");
  const int funnel = model.FindUnit("AU22_lip_funneler");
  const int stretch_l = model.FindUnit("AU20_lip_stretcher_L");
  const int stretch_r = model.FindUnit("AU20_lip_stretcher_R");
  const int blink_l = model.FindUnit("AU45_blink_L");
  const int blink_r = model.FindUnit("AU45_blink_R");
  HMC_CHECK(jaw_drop >= 0 && funnel >= 0 && stretch_l >= 0 && stretch_r >= 0 &&
            blink_l >= 0 && blink_r >= 0);

  std::vector<Eigen::VectorXd> out(options.frames);
  for (int f = 0; f < options.frames; ++f) {
    const double t = f / options.fps;
    Eigen::VectorXd a = model.ZeroActivations();
    for (const Event& e : events) {
      a[e.unit] += e.peak * Envelope(t, e.start, e.attack, e.hold, e.release);
    }
    for (const Speech& s : speech) {
      const double env = Envelope(t, s.start, 0.15, s.length, 0.2);
      if (env == 0) continue;
      const double syllable = 0.5 - 0.5 * std::cos(2 * M_PI * s.rate_hz * (t - s.start));
      a[jaw_drop] += env * (0.08 + 0.35 * syllable);
      // Rounded (oo) and spread (ee) lips alternate every few syllables.
      const double viseme = std::sin(2 * M_PI * 0.35 * s.rate_hz * (t - s.start) + s.phase);
      const double rounded = std::max(0.0, viseme), spread = std::max(0.0, -viseme);
      a[funnel] += env * 0.6 * rounded * rounded;
      a[stretch_l] += env * 0.45 * spread * spread;
      a[stretch_r] += env * 0.45 * spread * spread;
    }
    for (double b : blinks) {
      const double closure = Envelope(t, b, 0.08, 0.05, 0.17);
      a[blink_l] += closure;
      a[blink_r] += closure;
    }
    out[f] = a.cwiseMin(1.0);
  }
  return out;
}

}  // namespace

std::vector<Eigen::VectorXd> TruthActivations(
    const FaceModel& model, const std::vector<DatasetEntry>& plan,
    const TruthFramesOptions& options) {
  if (options.kind == "dataset") {
    std::vector<Eigen::VectorXd> out;
    for (const DatasetEntry& entry : plan) out.push_back(entry.activations);
    return out;
  }
  if (options.kind == "combos") return Combos(model, plan, options);
  if (options.kind == "performance") return Performance(model, options);
  throw InputError("unknown frames kind '" + options.kind + "'");
}

TruthFrames MakeTruthFrames(const FaceModel& model,
                            const std::vector<Marker>& markers,
                            const std::vector<DatasetEntry>& plan,
                            const TruthFramesOptions& options) {
  TruthFrames out;
  out.activations = TruthActivations(model, plan, options);
  const int num_frames = static_cast<int>(out.activations.size());
  out.positions.resize(num_frames);
  out.jaw.resize(num_frames);
  out.bundles.resize(num_frames);
  out.labels.resize(num_frames);
  SynthRandom noise = SynthRandom::Stream(static_cast<uint64_t>(options.seed), 12);
  const MatX3i& F = model.neutral().F;
  Progress progress("truth frames", num_frames);
  for (int f = 0; f < num_frames; ++f) {
    const int frame = out.start_frame + f;
    out.labels[f] = options.kind == "dataset" ? plan[f].name : options.kind;
    out.positions[f] = model.Evaluate(out.activations[f]);
    out.jaw[f] = {frame, model.JawPoseOf(out.activations[f])};
    out.bundles[f].frame = frame;
    for (const Marker& marker : markers) {
      Vec3 p = EvaluateSurfacePoint(marker.point, F, out.positions[f]);
      if (options.noise_mm > 0) {
        for (int i = 0; i < 3; ++i) p[i] += options.noise_mm * noise.Normal();
      }
      out.bundles[f].bundles[marker.name] = p;
    }
    progress.Advance();
  }
  progress.Finish();
  return out;
}

}  // namespace hmc
