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
  fields->Add("kind", &kind, "dataset | combos | performance | heldout | mixed")
      .OneOf(TruthFrameKinds());
  fields->Add("frames", &frames, "number of frames (combos, performance)").In(1, 100000);
  fields->Add("seed", &seed, "random seed of the activations and the bundle noise");
  fields->Add("noise_mm", &noise_mm, "std of Gaussian noise per bundle coordinate (mm)").In(0, 50);
  fields->Add("fps", &fps, "frame rate (frames per second)").Above(0).AtMost(1000);
  fields->Add("min_units", &min_units, "combos: fewest units active per frame").AtLeast(1);
  fields->Add("max_units", &max_units, "combos: most units active per frame");
  fields->Add("min_activation", &min_activation,
              "combos, heldout, mixed: activations drawn in [min, 1]")
      .Above(0).AtMost(1);
  fields->Add("held_min_units", &held_min_units,
              "heldout, mixed: fewest held-out units per frame")
      .AtLeast(1);
  fields->Add("held_max_units", &held_max_units,
              "heldout, mixed: most held-out units per frame");
}

const std::vector<std::string>& TruthFrameKinds() {
  static const std::vector<std::string> kinds = {"dataset", "combos", "performance",
                                                 "heldout", "mixed"};
  return kinds;
}

bool KindNeedsHeldOutUnits(const std::string& kind) {
  return kind == "heldout" || kind == "mixed";
}

bool TruthFramesOptions::Check() const {
  CHECK_OPTION_LIMITS();
  CHECK_OPTION_LE(min_units, max_units);
  CHECK_OPTION_LE(held_min_units, held_max_units);
  if (kind == "mixed" && max_units < 2) {
    spdlog::error("actor frames options: kind mixed needs max_units >= 2 (a held-out and a "
                  "dataset unit)");
    return false;
  }
  return true;
}

namespace {

// The units of the dataset (not held out), ascending; all units if none is
// held out.
std::vector<int> DatasetUnits(const FaceModel& model, const std::vector<int>& held) {
  std::vector<int> units;
  for (int k = 0; k < model.NumUnits(); ++k) {
    if (std::find(held.begin(), held.end(), k) == held.end()) units.push_back(k);
  }
  return units;
}

// Sets `count` distinct units of `pool` not yet active in `a` to activations
// drawn in [min_activation, 1]. `count` <= the pool's inactive units.
void PlaceUnits(const std::vector<int>& pool, int count, double min_activation,
                SynthRandom* rng, Eigen::VectorXd* a) {
  for (int placed = 0; placed < count;) {
    const int k = pool[rng->Index(static_cast<int>(pool.size()))];
    if ((*a)[k] != 0) continue;
    (*a)[k] = rng->Uniform(min_activation, 1.0);
    ++placed;
  }
}

// Random combinations of min..max distinct dataset units at fresh
// activations. With no held-out unit the pool is every unit in order, so
// the draws are those of the generator before holdout existed.
std::vector<Eigen::VectorXd> Combos(const FaceModel& model,
                                    const std::vector<DatasetEntry>& plan,
                                    const std::vector<int>& held,
                                    const TruthFramesOptions& options) {
  SynthRandom rng = SynthRandom::Stream(static_cast<uint64_t>(options.seed), 10);
  const std::vector<int> pool = DatasetUnits(model, held);
  const int num_units = static_cast<int>(pool.size());
  const int max_units = std::min(options.max_units, num_units);
  const int min_units = std::min(options.min_units, max_units);
  std::vector<Eigen::VectorXd> out;
  while (static_cast<int>(out.size()) < options.frames) {
    Eigen::VectorXd a = model.ZeroActivations();
    const int count = min_units + rng.Index(max_units - min_units + 1);
    PlaceUnits(pool, count, options.min_activation, &rng, &a);
    const bool in_dataset = std::any_of(plan.begin(), plan.end(), [&](const DatasetEntry& e) {
      return e.activations == a;
    });
    if (!in_dataset) out.push_back(std::move(a));
  }
  return out;
}

// heldout: combinations of held-out units alone. mixed: held-out and dataset
// units together. No frame can equal a dataset entry: every frame activates a
// unit that no entry activates.
std::vector<Eigen::VectorXd> HeldOutCombos(const FaceModel& model,
                                           const std::vector<int>& held,
                                           const TruthFramesOptions& options) {
  const bool mixed = options.kind == "mixed";
  SynthRandom rng =
      SynthRandom::Stream(static_cast<uint64_t>(options.seed), mixed ? 14 : 13);
  const std::vector<int> dataset_units = DatasetUnits(model, held);
  const int num_held = static_cast<int>(held.size());
  const int num_dataset = static_cast<int>(dataset_units.size());
  std::vector<Eigen::VectorXd> out(options.frames);
  for (Eigen::VectorXd& a : out) {
    a = model.ZeroActivations();
    if (!mixed) {
      const int hi = std::min(options.held_max_units, num_held);
      const int lo = std::min(options.held_min_units, hi);
      PlaceUnits(held, lo + rng.Index(hi - lo + 1), options.min_activation, &rng, &a);
      continue;
    }
    // Total 2..: at least one held-out and one dataset unit.
    const int max_total =
        std::min(options.max_units,
                 std::min(options.held_max_units, num_held) + num_dataset);
    const int min_total = std::min(std::max(options.min_units, 2), max_total);
    const int total = min_total + rng.Index(max_total - min_total + 1);
    const int held_hi = std::min({options.held_max_units, num_held, total - 1});
    const int held_lo = std::max(std::min(options.held_min_units, held_hi),
                                 total - num_dataset);
    const int num_held_here = held_lo + rng.Index(held_hi - held_lo + 1);
    PlaceUnits(held, num_held_here, options.min_activation, &rng, &a);
    PlaceUnits(dataset_units, total - num_held_here, options.min_activation, &rng, &a);
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
                                         const std::vector<int>& held,
                                         const TruthFramesOptions& options) {
  SynthRandom rng = SynthRandom::Stream(static_cast<uint64_t>(options.seed), 11);
  const int num_units = model.NumUnits();
  const double duration = options.frames / options.fps;
  struct Event {
    int unit;
    double start, attack, hold, release, peak;
  };
  std::vector<Event> events;
  // About one expression event per second, on non-jaw dataset units. (The
  // speech and blink tracks below keep their fixed units even if one of
  // them is held out.)
  std::vector<int> expression_units;
  for (int k = 0; k < num_units; ++k) {
    const bool is_held = std::find(held.begin(), held.end(), k) != held.end();
    if (!model.units()[k].drives_jaw && !is_held) expression_units.push_back(k);
  }
  HMC_CHECK(!expression_units.empty());
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
  // On an actor with held-out units, as in a real take, expressions the
  // dataset lacks too: one event on a held-out (non-jaw) unit per two
  // seconds (at least one), placed to be seen whole when the take allows.
  // Drawn after the dataset events, so those are the same as without.
  std::vector<int> held_units;
  for (int k : held) {
    if (!model.units()[k].drives_jaw) held_units.push_back(k);
  }
  if (!held_units.empty()) {
    const int num_held = std::max(1, static_cast<int>(std::ceil(duration / 2)));
    for (int e = 0; e < num_held; ++e) {
      Event event;
      event.unit = held_units[rng.Index(static_cast<int>(held_units.size()))];
      event.attack = rng.Uniform(0.25, 0.6);
      event.hold = rng.Uniform(0.2, 1.2);
      event.release = rng.Uniform(0.25, 0.7);
      event.start = rng.Uniform(
          0.0, std::max(0.0, duration - event.attack - event.hold));
      event.peak = rng.Uniform(0.3, 1.0);
      events.push_back(event);
    }
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
  // An empty plan says nothing about the dataset: no unit is held out (what
  // callers that pass {} for combos or performance always got).
  const std::vector<int> held =
      plan.empty() ? std::vector<int>() : UnitsNotInDataset(model, plan);
  if (options.kind == "combos") return Combos(model, plan, held, options);
  if (options.kind == "performance") return Performance(model, held, options);
  if (KindNeedsHeldOutUnits(options.kind)) {
    if (held.empty()) {
      throw InputError("frames of kind '" + options.kind +
                       "' need held-out units, but the dataset uses every "
                       "unit (synth.yaml: holdout 0; make the actor with "
                       "`hmc actor synth --holdout N`)");
    }
    return HeldOutCombos(model, held, options);
  }
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
