#include "synth/performance.h"

#include <algorithm>
#include <cmath>

#include <spdlog/spdlog.h>

#include "core/error.h"
#include "synth/synth_actor.h"
#include "synth/synth_random.h"
#include "synth/truth_frames.h"

namespace hmc {

void PerformanceOptions::Register(OptionFields* fields) {
  fields->Add("frames", &frames, "number of frames").In(1, 100000);
  fields->Add("seed", &seed, "random seed of expressions, slip and vibration");
  fields->Add("fps", &fps, "frame rate (frames per second)").Above(0).AtMost(1000);
  fields->Add("slip_mm", &slip_mm, "largest slip of the head in the helmet (mm)").In(0, 30);
  fields->Add("slip_deg", &slip_deg, "largest slip rotation (deg)").In(0, 20);
  fields->Add("vibration_mm", &vibration_mm, "amplitude of the helmet vibration (mm)").In(0, 5);
  fields->Add("vibration_deg", &vibration_deg, "amplitude of the vibration's rotation (deg)")
      .In(0, 2);
  fields->Add("vibration_hz", &vibration_hz, "main vibration frequency (Hz)").Above(0).AtMost(500);
  fields->Add("head_offset_mm", &head_offset_mm,
              "head placed this far from rest for the whole shot, random direction (mm)")
      .In(0, 40);
  fields->Add("head_offset_deg", &head_offset_deg,
              "and turned this much about a random axis through the head origin (deg)")
      .In(0, 30);
  fields->Add("brow_activity", &brow_activity,
              "peak of added slow brow raises/lowerings (activation; 0 = none)")
      .In(0, 1);
  fields->Add("jaw_activity", &jaw_activity,
              "peak of added slow jaw opening, swing, thrust (activation; 0 = none)")
      .In(0, 1);
  fields->Add("expression_scale", &expression_scale,
              "the performance's activations scaled by this (0 = a neutral hold)")
      .AtLeast(0)
      .AtMost(1);
}

bool PerformanceOptions::Check() const {
  CHECK_OPTION_LIMITS();
  return true;
}

namespace {

// A unit vector drawn uniformly on the sphere.
Vec3 RandomDirection(SynthRandom* rng) {
  Vec3 d(rng->Normal(), rng->Normal(), rng->Normal());
  return d.normalized();
}

// 0.5 - 0.5 cos: a smooth swell from 0 to 1 and back, once per period.
double Swell(double t_s, double hz, double phase) {
  return 0.5 - 0.5 * std::cos(2 * M_PI * hz * t_s + phase);
}

// Adds the slow brow and jaw tracks of brow_activity / jaw_activity (for
// stabilization and jaw tests: large motion on markers near the stable ones
// and on the jaw) to the performance's activations; clamped to [0, 1].
void AddBrowAndJawActivity(const FaceModel& model, const PerformanceOptions& options,
                           std::vector<Eigen::VectorXd>* activations) {
  if (options.brow_activity == 0 && options.jaw_activity == 0) return;
  SynthRandom rng = SynthRandom::Stream(static_cast<uint64_t>(options.seed), 52);
  const double brow_phase = rng.Uniform(0, 2 * M_PI);
  const double jaw_phase = rng.Uniform(0, 2 * M_PI);
  const double swing_phase = rng.Uniform(0, 2 * M_PI);
  const double thrust_phase = rng.Uniform(0, 2 * M_PI);
  auto unit = [&](const char* name) {
    const int k = model.FindUnit(name);
    HMC_CHECK(k >= 0);
    return k;
  };
  const int inner_l = unit("AU01_inner_brow_raiser_L"), inner_r = unit("AU01_inner_brow_raiser_R");
  const int outer_l = unit("AU02_outer_brow_raiser_L"), outer_r = unit("AU02_outer_brow_raiser_R");
  const int lowerer = unit("AU04_brow_lowerer"), jaw_drop = unit("AU26_jaw_drop");
  const int sideways_l = unit("AU30_jaw_sideways_L"), sideways_r = unit("AU30_jaw_sideways_R");
  const int thrust = unit("AU29_jaw_thrust");
  for (size_t f = 0; f < activations->size(); ++f) {
    const double t = f / options.fps;
    Eigen::VectorXd& a = (*activations)[f];
    // Brows: raise (0.4 Hz) with a lowering between raises.
    const double brow = std::sin(2 * M_PI * 0.4 * t + brow_phase);
    const double raise = options.brow_activity * std::max(0.0, brow);
    for (int k : {inner_l, inner_r, outer_l, outer_r}) a[k] += raise;
    a[lowerer] += 0.6 * options.brow_activity * std::max(0.0, -brow);
    // Jaw: opening (0.7 Hz), a swing to either side (0.3 Hz), thrust (0.23 Hz).
    const double swing = std::sin(2 * M_PI * 0.3 * t + swing_phase);
    a[jaw_drop] += options.jaw_activity * Swell(t, 0.7, jaw_phase);
    a[sideways_l] += 0.6 * options.jaw_activity * std::max(0.0, swing);
    a[sideways_r] += 0.6 * options.jaw_activity * std::max(0.0, -swing);
    a[thrust] += 0.5 * options.jaw_activity * Swell(t, 0.23, thrust_phase);
    a = a.cwiseMax(0.0).cwiseMin(1.0);
  }
}

}  // namespace

Rigid3 HeadFromHelmetAt(const PerformanceOptions& options, double t_s) {
  // The draws are redone per call (cheap) so the function is pure.
  SynthRandom rng = SynthRandom::Stream(static_cast<uint64_t>(options.seed), 50);
  const double duration = std::max(options.frames / options.fps, 1e-9);
  const double u = std::clamp(t_s / duration, -1.0, 2.0);
  // Slip: a drift that settles (smooth step) plus a slow wobble, each along
  // its own random direction; |slip| stays below the option's bound.
  const Vec3 drift_dir = RandomDirection(&rng);
  const Vec3 wobble_dir = RandomDirection(&rng);
  const Vec3 rot_drift_dir = RandomDirection(&rng);
  const Vec3 rot_wobble_dir = RandomDirection(&rng);
  const double phase = rng.Uniform(0, 2 * M_PI);
  const double cycles = rng.Uniform(0.6, 1.4);
  const double s = u * u * (3 - 2 * u);
  const double wobble = std::sin(2 * M_PI * cycles * u + phase);
  Vec3 translation = options.slip_mm * (0.7 * s * drift_dir + 0.3 * wobble * wobble_dir);
  Vec3 rotation_deg = options.slip_deg * (0.7 * s * rot_drift_dir + 0.3 * wobble * rot_wobble_dir);
  // Vibration: two close frequencies beat like a boom ringing.
  for (int k = 0; k < 2; ++k) {
    const double hz = options.vibration_hz * (k == 0 ? 1.0 : 1.73);
    const double weight = k == 0 ? 0.7 : 0.3;
    const Vec3 dir_t = RandomDirection(&rng);
    const Vec3 dir_r = RandomDirection(&rng);
    const double ph = rng.Uniform(0, 2 * M_PI);
    const double wave = std::sin(2 * M_PI * hz * t_s + ph);
    translation += weight * options.vibration_mm * wave * dir_t;
    rotation_deg += weight * options.vibration_deg * wave * dir_r;
  }
  Rigid3 out = Rigid3::Identity();
  const double angle = rotation_deg.norm() * M_PI / 180;
  if (angle > 0) {
    out.linear() = Eigen::AngleAxisd(angle, rotation_deg.normalized()).toRotationMatrix();
  }
  out.translation() = translation;
  if (options.head_offset_mm > 0 || options.head_offset_deg > 0) {
    // A constant placement of the head away from rest (its own stream, so
    // the other draws do not change): the head at rest maps to
    // offset * head, i.e. head_from_helmet gains offset^-1.
    SynthRandom offset_rng = SynthRandom::Stream(static_cast<uint64_t>(options.seed), 51);
    const Vec3 offset_dir = RandomDirection(&offset_rng);
    const Vec3 axis = RandomDirection(&offset_rng);
    Rigid3 helmet_from_placed = Rigid3::Identity();
    helmet_from_placed.linear() =
        Eigen::AngleAxisd(options.head_offset_deg * M_PI / 180, axis).toRotationMatrix();
    helmet_from_placed.translation() = options.head_offset_mm * offset_dir;
    out = out * helmet_from_placed.inverse();
  }
  return out;
}

ShotPerformance MakePerformance(const FaceModel& model,
                                const PerformanceOptions& options) {
  TruthFramesOptions truth;
  truth.kind = "performance";
  truth.frames = options.frames;
  truth.seed = options.seed;
  truth.fps = options.fps;
  ShotPerformance out;
  out.fps = options.fps;
  // The actor on camera can make every expression of its model: the plan
  // of a dataset that holds no unit out, so none is missing from the
  // performance (TruthActivations leaves out units absent from the plan).
  SynthActorOptions all_units;
  all_units.holdout = 0;
  all_units.holdout_units.clear();
  out.activations = TruthActivations(model, PlanDataset(model, all_units), truth);
  AddBrowAndJawActivity(model, options, &out.activations);
  for (Eigen::VectorXd& a : out.activations) a *= options.expression_scale;
  for (int f = 0; f < options.frames; ++f) {
    out.head_from_helmet.push_back(HeadFromHelmetAt(options, f / options.fps));
  }
  return out;
}

Eigen::VectorXd ActivationsAt(const ShotPerformance& performance, double t) {
  const std::vector<Eigen::VectorXd>& a = performance.activations;
  const int n = static_cast<int>(a.size());
  HMC_CHECK(n > 0);
  const int base = static_cast<int>(std::floor(t));  // the segment [base, base + 1]
  const double u = t - base;
  const auto at = [&](int i) -> const Eigen::VectorXd& { return a[std::clamp(i, 0, n - 1)]; };
  const Eigen::VectorXd& p0 = at(base - 1);
  const Eigen::VectorXd& p1 = at(base);
  const Eigen::VectorXd& p2 = at(base + 1);
  const Eigen::VectorXd& p3 = at(base + 2);
  const Eigen::VectorXd spline =
      0.5 * (2 * p1 + (p2 - p0) * u + (2 * p0 - 5 * p1 + 4 * p2 - p3) * u * u +
             (3 * p1 - p0 - 3 * p2 + p3) * u * u * u);
  return spline.cwiseMax(p1.cwiseMin(p2)).cwiseMin(p1.cwiseMax(p2));
}

}  // namespace hmc
