#include "synth/synth_actor.h"

#include <algorithm>
#include <map>
#include <set>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "core/error.h"
#include "core/logging.h"
#include "core/parallel.h"
#include "synth/face_model.h"
#include "synth/marker_layout.h"
#include "synth/synth_random.h"

namespace hmc {
namespace {

// At most this many units may be held out: enough for hard material, and
// the dataset keeps most of the face's motion.
constexpr int kMaxHoldout = 24;
// A bound against typos, not a recommendation: 10,000 shapes of the default
// 51,200-vertex mesh hold 12 GB of displacements.
constexpr int kMaxShapes = 10000;

}  // namespace

void SynthActorOptions::Register(OptionFields* fields) {
  fields->Add("seed", &seed, "random seed: face proportions, marker jitter, detail phases");
  fields->Add("name", &name, "actor name written to actor.yaml");
  fields->Add("grid_u", &grid_u, "vertex columns of the face grid").In(24, 4096);
  fields->Add("grid_v", &grid_v, "vertex rows of the face grid").In(20, 4096);
  fields->Add("proportion_jitter", &proportion_jitter,
              "relative spread of the seeded face proportions")
      .In(0, 0.15);
  fields->Add("detail_scale", &detail_scale, "scale of wrinkle and fold amplitudes").In(0, 5);
  fields->Add("marker_jitter_mm", &marker_jitter_mm,
              "std of the seeded marker placement jitter (mm)")
      .In(0, 3);
  fields->Add("dataset_inbetweens", &dataset_inbetweens,
              "add in-between shapes (50%, some 25/75%)");
  fields->Add("dataset_combos", &dataset_combos, "add the combination shapes");
  fields->Add("shapes", &shapes,
              "dataset size: 0 = the standard plan; more extends it with "
              "seeded in-betweens and pairwise and triple combinations of "
              "units that share a region (at least the standard plan's size)")
      .In(0, kMaxShapes);
  fields->Add("rig", &rig,
              "generator: the nonlinear generator with its jaw rig; linear: "
              "each unit's extreme as a fixed displacement, summed (no "
              "activation-dependent detail, no jaw rig); broad: linear too, "
              "each unit moving a broad, overlapping region as artists' FACS "
              "shapes do (the forehead to the hairline, the whole lower "
              "face, the temples and nose bridge), plus mouth_left/right; "
              "shapes without region tags")
      .OneOf({"generator", "linear", "broad"});
  fields->Add("holdout", &holdout,
              "action units held out of the dataset (drawn from the seed, "
              "never a jaw unit)")
      .In(0, kMaxHoldout);
  fields->Add("holdout_units", &holdout_units,
              "comma-separated unit names held out (overrides the seeded "
              "draw; synth.yaml records the resolved list)");
}

namespace {

// "a, b,c" -> {"a", "b", "c"}; empty items dropped.
std::vector<std::string> SplitNames(const std::string& text) {
  std::vector<std::string> names;
  std::string current;
  auto flush = [&] {
    const size_t begin = current.find_first_not_of(" \t");
    const size_t end = current.find_last_not_of(" \t");
    if (begin != std::string::npos) names.push_back(current.substr(begin, end - begin + 1));
    current.clear();
  };
  for (char c : text) {
    if (c == ',') {
      flush();
    } else {
      current += c;
    }
  }
  flush();
  return names;
}

}  // namespace

bool SynthActorOptions::Check() const {
  CHECK_OPTION_LIMITS();
  bool ok = true;
  auto fail = [&](const std::string& message) {
    spdlog::error("actor synth options: {}", message);
    ok = false;
  };
  if (name.empty()) fail("name must not be empty");
  const std::vector<std::string> names = SplitNames(holdout_units);
  if (!names.empty()) {
    if (holdout != 0 && holdout != static_cast<int>(names.size())) {
      fail(fmt::format("holdout is {} but holdout_units names {} units", holdout,
                       names.size()));
    }
    if (static_cast<int>(names.size()) > kMaxHoldout) {
      fail(fmt::format("holdout_units names more than {} units", kMaxHoldout));
    }
    for (size_t i = 0; i < names.size(); ++i) {
      for (size_t j = 0; j < i; ++j) {
        if (names[i] == names[j]) fail("holdout_units names '" + names[i] + "' twice");
      }
    }
  }
  return ok;
}

namespace {

// Selected combinations: expressions, speech visemes and jaw combinations.
const std::vector<std::pair<std::string, std::map<std::string, double>>>&
Combos() {
  static const std::vector<std::pair<std::string, std::map<std::string, double>>>
      combos = {
          {"combo_smile", {{"AU12_lip_corner_puller_L", 1}, {"AU12_lip_corner_puller_R", 1}}},
          {"combo_smile_cheekraise",
           {{"AU12_lip_corner_puller_L", 1}, {"AU12_lip_corner_puller_R", 1},
            {"AU06_cheek_raiser_L", 1}, {"AU06_cheek_raiser_R", 1}}},
          {"combo_smile_cheekraise_L",
           {{"AU12_lip_corner_puller_L", 1}, {"AU06_cheek_raiser_L", 1}}},
          {"combo_brow_raise",
           {{"AU01_inner_brow_raiser_L", 1}, {"AU01_inner_brow_raiser_R", 1},
            {"AU02_outer_brow_raiser_L", 1}, {"AU02_outer_brow_raiser_R", 1}}},
          {"combo_jawopen_funnel", {{"AU26_jaw_drop", 0.7}, {"AU22_lip_funneler", 1}}},
          {"combo_surprise",
           {{"AU01_inner_brow_raiser_L", 1}, {"AU01_inner_brow_raiser_R", 1},
            {"AU02_outer_brow_raiser_L", 1}, {"AU02_outer_brow_raiser_R", 1},
            {"AU05_upper_lid_raiser", 1}, {"AU26_jaw_drop", 0.6}}},
          {"combo_anger",
           {{"AU04_brow_lowerer", 1}, {"AU07_lid_tightener", 1}, {"AU24_lip_pressor", 1}}},
          {"combo_disgust", {{"AU09_nose_wrinkler", 1}, {"AU10_upper_lip_raiser", 1}}},
          {"combo_sad",
           {{"AU01_inner_brow_raiser_L", 1}, {"AU01_inner_brow_raiser_R", 1},
            {"AU04_brow_lowerer", 0.5}, {"AU15_lip_corner_depressor_L", 1},
            {"AU15_lip_corner_depressor_R", 1}}},
          {"combo_fear",
           {{"AU01_inner_brow_raiser_L", 1}, {"AU01_inner_brow_raiser_R", 1},
            {"AU04_brow_lowerer", 0.6}, {"AU20_lip_stretcher_L", 1},
            {"AU20_lip_stretcher_R", 1}, {"AU05_upper_lid_raiser", 1}}},
          {"combo_kiss", {{"AU18_lip_puckerer", 1}, {"AU22_lip_funneler", 0.6}}},
          {"combo_pucker_jaw", {{"AU18_lip_puckerer", 1}, {"AU26_jaw_drop", 0.3}}},
          {"combo_chin_press", {{"AU17_chin_raiser", 1}, {"AU24_lip_pressor", 1}}},
          {"combo_smile_jaw",
           {{"AU12_lip_corner_puller_L", 1}, {"AU12_lip_corner_puller_R", 1},
            {"AU26_jaw_drop", 0.6}}},
          {"combo_blink", {{"AU45_blink_L", 1}, {"AU45_blink_R", 1}}},
          {"combo_squint",
           {{"AU06_cheek_raiser_L", 1}, {"AU06_cheek_raiser_R", 1}, {"AU07_lid_tightener", 1}}},
          {"combo_sneer_L",
           {{"AU09_nose_wrinkler", 0.6}, {"AU10_upper_lip_raiser", 0.8},
            {"AU12_lip_corner_puller_L", 0.4}}},
          {"combo_jaw_left_open", {{"AU30_jaw_sideways_L", 1}, {"AU26_jaw_drop", 0.5}}},
          {"combo_jaw_right_open", {{"AU30_jaw_sideways_R", 1}, {"AU26_jaw_drop", 0.5}}},
          {"combo_jaw_thrust_open", {{"AU29_jaw_thrust", 1}, {"AU26_jaw_drop", 0.5}}},
          {"combo_scream",
           {{"AU27_mouth_stretch", 1}, {"AU26_jaw_drop", 0.5}, {"AU04_brow_lowerer", 0.7},
            {"AU20_lip_stretcher_L", 0.8}, {"AU20_lip_stretcher_R", 0.8}}},
          {"combo_lip_stretch", {{"AU20_lip_stretcher_L", 1}, {"AU20_lip_stretcher_R", 1}}},
          {"combo_grimace",
           {{"AU20_lip_stretcher_L", 1}, {"AU20_lip_stretcher_R", 1},
            {"AU04_brow_lowerer", 1}, {"AU07_lid_tightener", 1}, {"AU09_nose_wrinkler", 0.5}}},
          {"combo_puff_press", {{"AU34_cheek_puff", 1}, {"AU24_lip_pressor", 0.7}}},
          {"combo_dimple_smile",
           {{"AU14_dimpler", 1}, {"AU12_lip_corner_puller_L", 0.6},
            {"AU12_lip_corner_puller_R", 0.6}}},
          {"combo_frown",
           {{"AU15_lip_corner_depressor_L", 1}, {"AU15_lip_corner_depressor_R", 1},
            {"AU17_chin_raiser", 1}}},
          {"combo_speech_oo", {{"AU22_lip_funneler", 0.8}, {"AU18_lip_puckerer", 0.5},
                               {"AU26_jaw_drop", 0.3}}},
          {"combo_speech_ee",
           {{"AU20_lip_stretcher_L", 0.6}, {"AU20_lip_stretcher_R", 0.6},
            {"AU12_lip_corner_puller_L", 0.3}, {"AU12_lip_corner_puller_R", 0.3},
            {"AU26_jaw_drop", 0.2}}},
          {"combo_speech_aa", {{"AU26_jaw_drop", 0.75}, {"AU10_upper_lip_raiser", 0.3}}},
          {"combo_speech_mm", {{"AU24_lip_pressor", 0.6}, {"AU23_lip_tightener", 0.5}}},
      };
  return combos;
}

// Units with extra 25% and 75% in-betweens: the ones whose motion is large
// and most nonlinear in activation.
const std::vector<std::string>& FineInbetweenUnits() {
  static const std::vector<std::string> units = {
      "AU26_jaw_drop", "AU12_lip_corner_puller_L", "AU12_lip_corner_puller_R",
      "AU45_blink_L",  "AU45_blink_R",             "AU18_lip_puckerer"};
  return units;
}

// A shape's region tags: the union of its units'. The broad rig's shapes
// have none, as artists' rigs exported from a DCC (docs/synthetic.md,
// "Broad rig").
std::vector<std::string> UnionTags(const FaceModel& model,
                                   const Eigen::VectorXd& a) {
  std::vector<std::string> tags;
  if (model.broad()) return tags;
  for (int k = 0; k < model.NumUnits(); ++k) {
    if (a[k] == 0) continue;
    for (const std::string& tag : model.units()[k].tags) {
      if (std::find(tags.begin(), tags.end(), tag) == tags.end()) tags.push_back(tag);
    }
  }
  return tags;
}

}  // namespace

std::vector<int> HeldOutUnits(const FaceModel& model,
                              const SynthActorOptions& options,
                              const std::filesystem::path& source) {
  auto fail = [&](const std::string& message) {
    if (source.empty()) throw InputError(message);
    ThrowInputError(source, 0, "{}", message);
  };
  std::vector<int> held;
  const std::vector<std::string> names = SplitNames(options.holdout_units);
  if (!names.empty()) {
    if (options.holdout != 0 && options.holdout != static_cast<int>(names.size())) {
      fail(fmt::format("holdout is {} but holdout_units names {} units",
                       options.holdout, names.size()));
    }
    for (const std::string& name : names) {
      const int k = model.FindUnit(name);
      if (k < 0) fail("holdout_units: unknown action unit '" + name + "'");
      if (std::find(held.begin(), held.end(), k) != held.end()) {
        fail("holdout_units names '" + name + "' twice");
      }
      held.push_back(k);
    }
  } else if (options.holdout > 0) {
    // Jaw units are left in: they are the dataset's only source of jaw
    // rotation and the jaw drop alone is in a third of the combinations and
    // in the performance's speech, so a chance draw of one would change the
    // material far more than any other unit (docs/synthetic.md).
    std::vector<int> pool;
    for (int k = 0; k < model.NumUnits(); ++k) {
      if (!model.units()[k].drives_jaw) pool.push_back(k);
    }
    if (options.holdout > static_cast<int>(pool.size()) - 1) {
      fail(fmt::format("holdout {} leaves no expression unit in the dataset "
                       "({} units do not drive the jaw)",
                       options.holdout, pool.size()));
    }
    SynthRandom rng = SynthRandom::Stream(static_cast<uint64_t>(options.seed), 3);
    for (int i = 0; i < options.holdout; ++i) {
      const int j = i + rng.Index(static_cast<int>(pool.size()) - i);
      std::swap(pool[i], pool[j]);
      held.push_back(pool[i]);
    }
  }
  if (static_cast<int>(held.size()) >= model.NumUnits()) {
    fail("holdout_units would leave the dataset without any unit");
  }
  std::sort(held.begin(), held.end());
  return held;
}

SynthActorOptions ResolveHoldout(const FaceModel& model,
                                 const SynthActorOptions& options) {
  SynthActorOptions resolved = options;
  const std::vector<int> held = HeldOutUnits(model, options);
  resolved.holdout = static_cast<int>(held.size());
  resolved.holdout_units.clear();
  for (int k : held) {
    if (!resolved.holdout_units.empty()) resolved.holdout_units += ',';
    resolved.holdout_units += model.units()[k].name;
  }
  return resolved;
}

std::vector<int> UnitsNotInDataset(const FaceModel& model,
                                   const std::vector<DatasetEntry>& plan) {
  std::vector<int> missing;
  for (int k = 0; k < model.NumUnits(); ++k) {
    const bool used = std::any_of(plan.begin(), plan.end(), [&](const DatasetEntry& e) {
      return e.activations[k] != 0;
    });
    if (!used) missing.push_back(k);
  }
  return missing;
}

std::vector<DatasetEntry> PlanDataset(const FaceModel& model,
                                      const SynthActorOptions& options) {
  const std::vector<int> held = HeldOutUnits(model, options);
  std::vector<DatasetEntry> plan;
  auto add = [&](std::string name, Eigen::VectorXd a) {
    for (int k : held) {
      if (a[k] != 0) return;
    }
    std::vector<std::string> tags = UnionTags(model, a);
    plan.push_back({std::move(name), std::move(a), std::move(tags)});
  };
  const int num_units = model.NumUnits();
  for (int k = 0; k < num_units; ++k) {
    std::vector<double> levels = {1.0};
    if (options.dataset_inbetweens) {
      levels.push_back(0.5);
      const auto& fine = FineInbetweenUnits();
      if (std::find(fine.begin(), fine.end(), model.units()[k].name) != fine.end()) {
        levels.push_back(0.25);
        levels.push_back(0.75);
      }
    }
    for (double level : levels) {
      Eigen::VectorXd a = model.ZeroActivations();
      a[k] = level;
      add(fmt::format("{}_{:03d}", model.units()[k].name,
                      static_cast<int>(std::lround(level * 100))),
          a);
    }
  }
  if (options.dataset_combos) {
    for (const auto& [name, units] : Combos()) {
      Eigen::VectorXd a = model.ZeroActivations();
      for (const auto& [unit, level] : units) {
        const int k = model.FindUnit(unit);
        HMC_CHECK_MSG(k >= 0, "combo " + name + " names unknown unit " + unit);
        a[k] = level;
      }
      add(name, a);
    }
  }
  if (options.shapes > 0) {
    if (options.shapes < static_cast<int>(plan.size())) {
      throw InputError(fmt::format(
          "shapes {} is below the standard plan's {} shapes (extremes, "
          "in-betweens and combinations); use 0 for the standard plan or turn "
          "dataset_inbetweens / dataset_combos off",
          options.shapes, plan.size()));
    }
    ExtendDataset(model, held, options.seed, options.shapes, &plan);
  }
  return plan;
}

void ExtendDataset(const FaceModel& model, const std::vector<int>& held, int seed,
                   int count, std::vector<DatasetEntry>* plan) {
  const int num_units = model.NumUnits();
  std::vector<int> pool;  // the units that may be drawn
  for (int k = 0; k < num_units; ++k) {
    if (!std::binary_search(held.begin(), held.end(), k)) pool.push_back(k);
  }
  HMC_CHECK(!pool.empty());
  auto share_tag = [&](int a, int b) {
    for (const std::string& tag : model.units()[a].tags) {
      const auto& other = model.units()[b].tags;
      if (std::find(other.begin(), other.end(), tag) != other.end()) return true;
    }
    return false;
  };
  // Entries are told apart by their activations: a drawn pair can equal a
  // named combination of the standard plan (combo_smile).
  auto key = [](const Eigen::VectorXd& a) {
    return std::vector<double>(a.data(), a.data() + a.size());
  };
  std::set<std::vector<double>> planned;
  for (const DatasetEntry& e : *plan) planned.insert(key(e.activations));
  SynthRandom rng = SynthRandom::Stream(static_cast<uint64_t>(seed), 11);
  // A draw that repeats an entry is drawn again. The units' pairs and
  // triples at 17 levels each form far more distinct entries than
  // kMaxShapes, so the loop ends; the bound turns an impossible request
  // into a loud failure instead of a hang.
  const int64_t max_draws = 1000 * static_cast<int64_t>(count) + 100000;
  for (int64_t draw = 0; static_cast<int>(plan->size()) < count; ++draw) {
    HMC_CHECK_MSG(draw < max_draws, "ExtendDataset: too few distinct entries");
    // 1, 2 or 3 units, in the proportions 1 : 2 : 2.
    const double kind = rng.Uniform();
    const int want = kind < 0.2 ? 1 : kind < 0.6 ? 2 : 3;
    std::vector<int> units = {pool[rng.Index(static_cast<int>(pool.size()))]};
    while (static_cast<int>(units.size()) < want) {
      std::vector<int> near;  // shares a region with a unit already drawn
      for (int k : pool) {
        if (std::find(units.begin(), units.end(), k) != units.end()) continue;
        if (std::any_of(units.begin(), units.end(),
                        [&](int u) { return share_tag(u, k); })) {
          near.push_back(k);
        }
      }
      if (near.empty()) break;
      units.push_back(near[rng.Index(static_cast<int>(near.size()))]);
    }
    std::sort(units.begin(), units.end());
    Eigen::VectorXd a = model.ZeroActivations();
    std::string name;
    for (int k : units) {
      const int percent = 20 + 5 * rng.Index(17);  // 20, 25, ..., 100
      a[k] = percent / 100.0;
      if (!name.empty()) name += "__";
      name += fmt::format("{}_{:03d}", model.units()[k].name, percent);
    }
    if (!planned.insert(key(a)).second) continue;  // already in the plan
    std::vector<std::string> tags = UnionTags(model, a);
    plan->push_back({std::move(name), std::move(a), std::move(tags)});
  }
}

Actor SynthesizeActorFromModel(const FaceModel& model,
                               const SynthActorOptions& options) {
  Actor actor;
  actor.name = options.name;
  actor.units = "mm";
  actor.neutral = model.neutral();
  if (model.has_jaw_rig()) actor.jaw_rig = model.jaw_rig();
  actor.markers = LayoutMarkers(model.face(), static_cast<uint64_t>(options.seed),
                                options.marker_jitter_mm);
  const std::vector<DatasetEntry> plan = PlanDataset(model, options);
  actor.shapes.resize(plan.size());
  // Each evaluation is parallel over vertices; shapes go one after another.
  Progress progress("dataset shapes", static_cast<int64_t>(plan.size()), "shapes");
  for (size_t n = 0; n < plan.size(); ++n) {
    Shape& shape = actor.shapes[n];
    shape.name = plan[n].name;
    shape.tags = plan[n].tags;
    shape.jaw = model.JawPoseOf(plan[n].activations);
    shape.displacement = model.Evaluate(plan[n].activations) - model.neutral().V;
    progress.Advance();
  }
  progress.Finish();
  return actor;
}

void WriteSynthActorOptions(const SynthActorOptions& options,
                            const std::filesystem::path& actor_dir) {
  SynthActorOptions copy = options;
  OptionFields fields;
  copy.Register(&fields);
  WriteOptionsUsed(fields, actor_dir / kSynthOptionsFile);
}

SynthActorOptions ReadSynthActorOptions(const std::filesystem::path& actor_dir) {
  const std::filesystem::path file = actor_dir / kSynthOptionsFile;
  if (!std::filesystem::exists(file)) {
    ThrowInputError(file, 0,
                    "missing: not a synthetic actor package (`hmc actor "
                    "synth` writes the generator options there)");
  }
  SynthActorOptions options;
  OptionFields fields;
  options.Register(&fields);
  fields.LoadYamlFile(file);
  if (!options.Check()) {
    ThrowInputError(file, 0, "invalid generator options (see the message above)");
  }
  return options;
}

void CheckActorMatchesModel(const Actor& actor, const FaceModel& model,
                            double tolerance_mm) {
  const std::filesystem::path file = actor.dir / "neutral.obj";
  const TriMesh& mine = model.neutral();
  if (mine.NumVertices() != actor.NumVertices() ||
      mine.NumFaces() != actor.neutral.NumFaces() || mine.F != actor.neutral.F) {
    ThrowInputError(file, 0,
                    "does not match the generator in {} ({} vertices and {} "
                    "triangles regenerated, {} and {} loaded): the package "
                    "was edited or is stale",
                    kSynthOptionsFile, mine.NumVertices(), mine.NumFaces(),
                    actor.NumVertices(), actor.neutral.NumFaces());
  }
  const double difference = (mine.V - actor.neutral.V).cwiseAbs().maxCoeff();
  if (!(difference <= tolerance_mm)) {
    ThrowInputError(file, 0,
                    "does not match the generator in {} (vertex positions "
                    "differ by up to {:.3g} mm): the package was edited or "
                    "is stale",
                    kSynthOptionsFile, difference);
  }
}

SynthPackage::SynthPackage() = default;
SynthPackage::SynthPackage(SynthPackage&&) noexcept = default;
SynthPackage::~SynthPackage() = default;

SynthPackage LoadSynthPackage(const std::filesystem::path& dir) {
  SynthPackage p;
  p.synth_file = dir / kSynthOptionsFile;
  p.options = ReadSynthActorOptions(dir);
  p.actor = LoadActor(dir);
  p.model = std::make_unique<FaceModel>(p.options);
  CheckActorMatchesModel(p.actor, *p.model, kSynthPackageToleranceMm);
  return p;
}

Actor SynthesizeActor(const SynthActorOptions& options) {
  if (!options.Check()) {
    throw InputError("invalid synthetic actor options (see the message above)");
  }
  const FaceModel model(options);
  return SynthesizeActorFromModel(model, options);
}

}  // namespace hmc
