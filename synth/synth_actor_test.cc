#include "synth/synth_actor.h"

#include <algorithm>
#include <array>
#include <filesystem>
#include <set>

#include <fmt/format.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include "core/error.h"
#include "core/file_util.h"
#include "synth/face_model.h"

namespace hmc {
namespace {

SynthActorOptions Small(int seed = 1) {
  SynthActorOptions options;
  options.seed = seed;
  options.grid_u = 40;
  options.grid_v = 32;
  return options;
}

TEST(SynthActorTest, SmallActorIsAValidPackage) {
  const Actor actor = SynthesizeActor(Small());
  EXPECT_NO_THROW(ValidateActor(actor, "synth"));
  EXPECT_EQ(actor.NumVertices(), 40 * 32);
  EXPECT_GE(actor.markers.size(), 120u);
  ASSERT_TRUE(actor.jaw_rig.has_value());
  EXPECT_EQ(actor.jaw_rig->weights.size(), actor.NumVertices());
  EXPECT_GE(actor.shapes.size(), 80u);
  std::set<std::string> names;
  for (const Shape& shape : actor.shapes) {
    EXPECT_TRUE(names.insert(shape.name).second) << shape.name;
    EXPECT_FALSE(shape.tags.empty()) << shape.name;
    EXPECT_EQ(shape.displacement.rows(), actor.NumVertices());
  }
  for (const std::string name :
       {"AU12_lip_corner_puller_L_100", "AU12_lip_corner_puller_L_050",
        "AU26_jaw_drop_025", "combo_smile_cheekraise", "combo_brow_raise",
        "combo_jawopen_funnel"}) {
    EXPECT_GE(actor.FindShape(name), 0) << name;
  }
  const Shape& drop = actor.shapes[actor.FindShape("AU26_jaw_drop_100")];
  EXPECT_GT(drop.jaw.open_deg, 20.0);
  EXPECT_TRUE(actor.shapes[actor.FindShape("AU04_brow_lowerer_100")].jaw.IsZero());
}

TEST(SynthActorTest, DatasetSizeFollowsOptions) {
  SynthActorOptions options = Small();
  const FaceModel model(options);
  const size_t full = PlanDataset(model, options).size();
  options.dataset_combos = false;
  const size_t no_combos = PlanDataset(model, options).size();
  options.dataset_inbetweens = false;
  const size_t extremes = PlanDataset(model, options).size();
  EXPECT_EQ(extremes, static_cast<size_t>(model.NumUnits()));
  EXPECT_GT(no_combos, extremes + static_cast<size_t>(model.NumUnits()) - 1);
  EXPECT_GE(full - no_combos, 20u);
  EXPECT_GE(full, 80u);
}

TEST(SynthActorTest, ShapesAreTheModelsEvaluations) {
  const SynthActorOptions options = Small(3);
  const FaceModel model(options);
  const Actor actor = SynthesizeActorFromModel(model, options);
  const std::vector<DatasetEntry> plan = PlanDataset(model, options);
  ASSERT_EQ(plan.size(), actor.shapes.size());
  for (size_t n = 0; n < plan.size(); n += 7) {
    EXPECT_EQ(actor.ShapePositions(static_cast<int>(n)),
              model.neutral().V + (model.Evaluate(plan[n].activations) - model.neutral().V));
    EXPECT_EQ(actor.shapes[n].jaw.ToArray(), model.JawPoseOf(plan[n].activations).ToArray());
  }
}

// A linear-rig or broad-rig actor: no jaw rig, zero jaw poses, in-betweens
// on the line to their extreme and combinations the sums of their units'
// extremes.
TEST(SynthActorTest, LinearRigDatasetIsLinear) {
  for (const auto& [rig, seed] : {std::make_pair("linear", 1), std::make_pair("linear", 2),
                                  std::make_pair("broad", 3), std::make_pair("broad", 4)}) {
    SCOPED_TRACE(rig);
    SynthActorOptions options = Small(seed);
    options.rig = rig;
    ASSERT_TRUE(options.Check());
    const FaceModel model(options);
    const Actor actor = SynthesizeActorFromModel(model, options);
    EXPECT_NO_THROW(ValidateActor(actor, "synth"));
    EXPECT_FALSE(actor.jaw_rig.has_value());
    const std::vector<DatasetEntry> plan = PlanDataset(model, options);
    ASSERT_EQ(plan.size(), actor.shapes.size());
    // The extremes by unit.
    std::vector<int> extreme(model.NumUnits(), -1);
    for (size_t n = 0; n < plan.size(); ++n) {
      EXPECT_TRUE(actor.shapes[n].jaw.IsZero()) << actor.shapes[n].name;
      const Eigen::VectorXd& a = plan[n].activations;
      if ((a.array() != 0).count() == 1 && a.maxCoeff() == 1.0) {
        int k = 0;
        a.maxCoeff(&k);
        extreme[k] = static_cast<int>(n);
      }
    }
    int inbetweens = 0, combos = 0;
    for (size_t n = 0; n < plan.size(); ++n) {
      const Eigen::VectorXd& a = plan[n].activations;
      MatX3d sum = MatX3d::Zero(actor.NumVertices(), 3);
      for (int k = 0; k < model.NumUnits(); ++k) {
        if (a[k] == 0) continue;
        ASSERT_GE(extreme[k], 0);
        sum += a[k] * actor.shapes[extreme[k]].displacement;
      }
      EXPECT_LT((actor.shapes[n].displacement - sum).cwiseAbs().maxCoeff(),
                1e-9)
          << actor.shapes[n].name;
      const int active = static_cast<int>((a.array() != 0).count());
      if (active == 1 && a.maxCoeff() < 1.0) ++inbetweens;
      if (active >= 2) ++combos;
    }
    EXPECT_GE(inbetweens, 20);
    EXPECT_GE(combos, 20);
  }
  SynthActorOptions bad = Small();
  bad.rig = "quadratic";
  EXPECT_FALSE(bad.Check());
}

// Each marker's motion (mm) in each shape: the displacement at its point.
std::vector<std::vector<Vec3>> MarkerMotion(const Actor& actor) {
  std::vector<std::vector<Vec3>> motion(actor.shapes.size());
  for (size_t n = 0; n < actor.shapes.size(); ++n) {
    for (const Marker& m : actor.markers) {
      motion[n].push_back(
          EvaluateSurfacePoint(m.point, actor.neutral.F, actor.shapes[n].displacement));
    }
  }
  return motion;
}

// What makes the broad rig an artist's rig (docs/synthetic.md, "Broad rig"):
// the stable-tagged markers move in many shapes (on the generator, in none),
// a brow raise lifts the whole forehead to the top row, a smile lifts the
// cheek up to the lower lid, jaw forward and mouth left/right move the whole
// lower face, cheek puff, nose wrinkle and squint reach the cheeks, nose
// bridge and temples, and most markers are moved by several units.
TEST(SynthActorTest, BroadRigMovesBroadOverlappingRegions) {
  for (int seed : {3, 8, 21}) {
    SCOPED_TRACE(seed);
    SynthActorOptions options = Small(seed);
    options.rig = "broad";
    const FaceModel model(options);
    const Actor actor = SynthesizeActorFromModel(model, options);
    const std::vector<std::vector<Vec3>> motion = MarkerMotion(actor);
    const int num_markers = static_cast<int>(actor.markers.size());
    auto shape = [&](const std::string& name) {
      const int n = actor.FindShape(name);
      EXPECT_GE(n, 0) << name;
      return std::max(n, 0);
    };
    auto height = [&](int j) {
      return EvaluateSurfacePoint(actor.markers[j].point, actor.neutral.F, actor.neutral.V).y();
    };
    auto starts = [&](int j, const std::string& prefix) {
      return actor.markers[j].name.rfind(prefix, 0) == 0;
    };
    for (const Shape& s : actor.shapes) EXPECT_TRUE(s.tags.empty()) << s.name;

    // Stable markers that move by more than 1 mm in at least 10 shapes: half
    // of them on the broad rig, none with the same layout on the generator.
    auto stable_moving = [](const Actor& a, const std::vector<std::vector<Vec3>>& m) {
      int moving = 0;
      for (size_t j = 0; j < a.markers.size(); ++j) {
        if (!a.markers[j].HasTag("stable")) continue;
        int shapes = 0;
        for (const auto& shape_motion : m) shapes += shape_motion[j].norm() > 1.0;
        moving += shapes >= 10;
      }
      return moving;
    };
    const int stable = static_cast<int>(std::count_if(
        actor.markers.begin(), actor.markers.end(),
        [](const Marker& m) { return m.HasTag("stable"); }));
    EXPECT_GE(stable, 15);
    EXPECT_GE(stable_moving(actor, motion), stable / 2);
    const Actor generator = SynthesizeActor(Small(seed));
    EXPECT_EQ(stable_moving(generator, MarkerMotion(generator)), 0);
    RecordProperty("stable_moving_broad", std::to_string(stable_moving(actor, motion)));

    const auto& brow = motion[shape("combo_brow_raise")];
    const auto& smile = motion[shape("AU12_lip_corner_puller_L_100")];
    const auto& thrust = motion[shape("AU29_jaw_thrust_100")];
    const auto& left = motion[shape("mouth_left_100")];
    const auto& right = motion[shape("mouth_right_100")];
    const auto& puff = motion[shape("AU34_cheek_puff_100")];
    const auto& wrinkle = motion[shape("AU09_nose_wrinkler_100")];
    const auto& squint = motion[shape("AU07_lid_tightener_100")];
    const double nose_tip = model.face().proportions.nose_tip_t;
    int forehead = 0, lids = 0, lower = 0, bridges = 0, temples = 0;
    for (int j = 0; j < num_markers; ++j) {
      const std::string& name = actor.markers[j].name;
      if (starts(j, "forehead")) {  // every row, the top one (stable) too
        ++forehead;
        EXPECT_GT(brow[j].y(), 1.5) << name;
      }
      // The lower lid and below the left eye, and the left cheek.
      for (const char* lid : {"eye_l_04", "eye_l_05", "eye_l_06", "eye_l_09", "eye_l_10",
                              "eye_l_11"}) {
        if (name == lid) {
          ++lids;
          EXPECT_GT(smile[j].y(), 0.5) << name;
        }
      }
      if (starts(j, "cheek_l")) {
        EXPECT_GT(smile[j].norm(), 1.0) << name;
      }
      if (starts(j, "cheek_")) {
        EXPECT_GT(puff[j].norm(), 1.5) << name;
      }
      // The whole lower face: every marker below the nose tip.
      if (height(j) < nose_tip) {
        ++lower;
        EXPECT_GT(thrust[j].z(), 1.0) << name;
        EXPECT_GT(left[j].x(), 0.5) << name;
        EXPECT_LT(right[j].x(), -0.5) << name;
      }
      if (starts(j, "nose_bridge")) {
        ++bridges;
        EXPECT_GT(wrinkle[j].y(), 1.0) << name;
      }
      if (starts(j, "temple")) {
        ++temples;
        EXPECT_GT(squint[j].norm(), 0.5) << name;
      }
    }
    EXPECT_GE(forehead, 25);
    EXPECT_EQ(lids, 6);
    EXPECT_GE(lower, 60);
    EXPECT_EQ(bridges, 3);
    EXPECT_EQ(temples, 4);

    // Overlap: markers moved by more than 0.5 mm by at least two units'
    // extremes, against the linear rig of the same seed.
    auto overlapped = [&](const Actor& a, const std::vector<std::vector<Vec3>>& m) {
      int count = 0;
      for (int j = 0; j < num_markers; ++j) {
        int units = 0;
        for (size_t n = 0; n < a.shapes.size(); ++n) {
          const std::string& name = a.shapes[n].name;
          if (name.size() > 4 && name.compare(name.size() - 4, 4, "_100") == 0) {
            units += m[n][j].norm() > 0.5;
          }
        }
        count += units >= 2;
      }
      return static_cast<double>(count) / num_markers;
    };
    SynthActorOptions linear_options = Small(seed);
    linear_options.rig = "linear";
    const Actor linear = SynthesizeActor(linear_options);
    const double broad_overlap = overlapped(actor, motion);
    const double linear_overlap = overlapped(linear, MarkerMotion(linear));
    EXPECT_GE(broad_overlap, 0.95);
    EXPECT_GT(broad_overlap, linear_overlap + 0.1);
    RecordProperty("overlap_broad", std::to_string(broad_overlap));
    RecordProperty("overlap_linear", std::to_string(linear_overlap));
  }
}

TEST(SynthActorTest, DeterministicBySeed) {
  for (const std::string rig : {"generator", "broad"}) {
    SCOPED_TRACE(rig);
    SynthActorOptions five = Small(5), six = Small(6);
    five.rig = six.rig = rig;
    const Actor a = SynthesizeActor(five), b = SynthesizeActor(five);
    const Actor c = SynthesizeActor(six);
    EXPECT_EQ(a.neutral.V, b.neutral.V);
    ASSERT_EQ(a.shapes.size(), b.shapes.size());
    for (size_t n = 0; n < a.shapes.size(); ++n) {
      EXPECT_EQ(a.shapes[n].displacement, b.shapes[n].displacement);
    }
    for (size_t m = 0; m < a.markers.size(); ++m) {
      EXPECT_EQ(a.markers[m].point.face, b.markers[m].point.face);
      EXPECT_EQ(a.markers[m].point.bary, b.markers[m].point.bary);
    }
    EXPECT_GT((a.neutral.V - c.neutral.V).cwiseAbs().maxCoeff(), 0.5);
    double shape_difference = 0;
    for (size_t n = 0; n < a.shapes.size(); ++n) {
      shape_difference = std::max(
          shape_difference,
          (a.shapes[n].displacement - c.shapes[n].displacement).cwiseAbs().maxCoeff());
    }
    EXPECT_GT(shape_difference, 0.1);
  }
}

TEST(SynthActorTest, OptionsCheckAndYamlRoundTrip) {
  SynthActorOptions options;
  EXPECT_TRUE(options.Check());
  options.grid_u = 10;
  EXPECT_FALSE(options.Check());
  EXPECT_THROW(SynthesizeActor(options), InputError);
  options = SynthActorOptions();
  options.marker_jitter_mm = -1;
  EXPECT_FALSE(options.Check());

  SynthActorOptions written;
  written.seed = 42;
  written.grid_u = 77;
  written.detail_scale = 0.5;
  written.dataset_combos = false;
  OptionFields out;
  written.Register(&out);
  const YAML::Node yaml = out.ToYaml();
  SynthActorOptions read;
  OptionFields in;
  read.Register(&in);
  in.LoadYaml(yaml, "synth.yaml");
  EXPECT_EQ(read.seed, 42);
  EXPECT_EQ(read.grid_u, 77);
  EXPECT_EQ(read.detail_scale, 0.5);
  EXPECT_FALSE(read.dataset_combos);
}

TEST(SynthActorTest, PackageRoundTripRegeneratesTheModel) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() /
                       fmt::format("hmc_synth_actor_test_{}", getpid());
  fs::remove_all(dir);
  SynthActorOptions options = Small(11);
  options.dataset_combos = false;
  WriteActor(SynthesizeActor(options), dir);
  WriteSynthActorOptions(options, dir);
  // What `hmc actor frames` does: rebuild the generator from synth.yaml and
  // compare it with the loaded package.
  const SynthActorOptions read = ReadSynthActorOptions(dir);
  EXPECT_EQ(read.seed, 11);
  const Actor loaded = LoadActor(dir);
  const FaceModel model(read);
  EXPECT_NO_THROW(CheckActorMatchesModel(loaded, model, 1e-4));
  EXPECT_EQ(PlanDataset(model, read).size(), loaded.shapes.size());
  // Another seed's generator is refused, and so is an edited neutral.
  SynthActorOptions other = read;
  other.seed = 12;
  EXPECT_THROW(CheckActorMatchesModel(loaded, FaceModel(other), 1e-4), InputError);
  Actor edited = loaded;
  edited.neutral.V(100, 2) += 0.01;
  EXPECT_THROW(CheckActorMatchesModel(edited, model, 1e-4), InputError);
  // A package without synth.yaml, or with a bad one, is refused.
  WriteFileAtomic(dir / kSynthOptionsFile, std::string("seed: 1\nsize: 3\n"));
  EXPECT_THROW(ReadSynthActorOptions(dir), InputError);
  fs::remove(dir / kSynthOptionsFile);
  EXPECT_THROW(ReadSynthActorOptions(dir), InputError);
  fs::remove_all(dir);
}

// The names of `plan`'s entries.
std::vector<std::string> Names(const std::vector<DatasetEntry>& plan) {
  std::vector<std::string> names;
  for (const DatasetEntry& entry : plan) names.push_back(entry.name);
  return names;
}

bool UsesAny(const DatasetEntry& entry, const std::vector<int>& units) {
  for (int k : units) {
    if (entry.activations[k] != 0) return true;
  }
  return false;
}

TEST(SynthActorTest, HoldoutRemovesExactlyTheShapesUsingHeldOutUnits) {
  std::set<std::vector<int>> drawn;
  for (int seed : {1, 2, 3, 9}) {
    SynthActorOptions options = Small(seed);
    const FaceModel model(options);
    EXPECT_TRUE(HeldOutUnits(model, options).empty());
    const std::vector<DatasetEntry> full = PlanDataset(model, options);
    EXPECT_TRUE(UnitsNotInDataset(model, full).empty());
    for (int count : {1, 3, 6}) {
      options.holdout = count;
      ASSERT_TRUE(options.Check());
      const std::vector<int> held = HeldOutUnits(model, options);
      ASSERT_EQ(static_cast<int>(held.size()), count);
      EXPECT_TRUE(std::is_sorted(held.begin(), held.end()));
      EXPECT_EQ(std::set<int>(held.begin(), held.end()).size(), held.size());
      for (int k : held) EXPECT_FALSE(model.units()[k].drives_jaw) << model.units()[k].name;
      if (count == 3) drawn.insert(held);
      // Deterministic by seed.
      EXPECT_EQ(HeldOutUnits(model, options), held);

      const std::vector<DatasetEntry> plan = PlanDataset(model, options);
      // Exactly the full plan without the entries that use a held-out unit,
      // in the same order and with the same activations.
      std::vector<DatasetEntry> expected;
      for (const DatasetEntry& entry : full) {
        if (!UsesAny(entry, held)) expected.push_back(entry);
      }
      ASSERT_EQ(Names(plan), Names(expected));
      for (size_t n = 0; n < plan.size(); ++n) {
        EXPECT_EQ(plan[n].activations, expected[n].activations);
        EXPECT_EQ(plan[n].tags, expected[n].tags);
      }
      // Every held-out unit removed at least its extreme and in-between.
      EXPECT_LE(plan.size() + 2 * held.size(), full.size());
      EXPECT_EQ(UnitsNotInDataset(model, plan), held);
    }
  }
  // Different seeds hold out different units.
  EXPECT_GT(drawn.size(), 1u);
}

// --shapes N: exactly N entries, the standard plan first, every smaller
// size a prefix of a larger one, no repeats, no held-out unit, and every
// combination of units that share a region (so it adds points to a cloud).
TEST(SynthActorTest, LargerDatasetsExtendTheStandardPlan) {
  for (int seed : {1, 2, 5}) {
    SynthActorOptions options = Small(seed);
    options.holdout = 2;
    const FaceModel model(options);
    const std::vector<int> held = HeldOutUnits(model, options);
    const std::vector<DatasetEntry> standard = PlanDataset(model, options);
    const std::vector<std::string> standard_names = Names(standard);
    std::vector<std::string> previous;
    for (int shapes : {static_cast<int>(standard.size()), 250, 600}) {
      options.shapes = shapes;
      ASSERT_TRUE(options.Check());
      const std::vector<DatasetEntry> plan = PlanDataset(model, options);
      ASSERT_EQ(plan.size(), static_cast<size_t>(shapes));
      const std::vector<std::string> names = Names(plan);
      EXPECT_TRUE(std::equal(previous.begin(), previous.end(), names.begin()));
      EXPECT_TRUE(std::equal(standard_names.begin(), standard_names.end(), names.begin()));
      EXPECT_EQ(std::set<std::string>(names.begin(), names.end()).size(), names.size());
      std::set<std::vector<double>> activations;
      std::array<int, 4> kinds = {0, 0, 0, 0};
      for (size_t n = 0; n < plan.size(); ++n) {
        const Eigen::VectorXd& a = plan[n].activations;
        EXPECT_TRUE(activations.insert({a.data(), a.data() + a.size()}).second) << plan[n].name;
        EXPECT_FALSE(UsesAny(plan[n], held)) << plan[n].name;
        if (n < standard.size()) continue;
        std::vector<int> used;
        for (int k = 0; k < a.size(); ++k) {
          if (a[k] == 0) continue;
          used.push_back(k);
          EXPECT_GE(a[k], 0.2 - 1e-12);
          EXPECT_LE(a[k], 1.0);
        }
        ASSERT_GE(used.size(), 1u);
        ASSERT_LE(used.size(), 3u);
        ++kinds[used.size()];
        // Each unit shares a region tag with another one of the entry.
        for (int u : used) {
          if (used.size() == 1) break;
          bool shares = false;
          for (int v : used) {
            if (v == u) continue;
            for (const std::string& tag : model.units()[u].tags) {
              const auto& t = model.units()[v].tags;
              shares = shares || std::find(t.begin(), t.end(), tag) != t.end();
            }
          }
          EXPECT_TRUE(shares) << plan[n].name;
        }
      }
      if (shapes == 600) {
        for (int k = 1; k <= 3; ++k) EXPECT_GT(kinds[k], 50) << k << " units";
      }
      previous = names;
    }
    options.shapes = static_cast<int>(standard.size()) - 1;
    EXPECT_THROW(PlanDataset(model, options), InputError);
  }
  SynthActorOptions bad = Small();
  bad.shapes = -1;
  EXPECT_FALSE(bad.Check());
}

TEST(SynthActorTest, NamedHoldoutUnitsAndTheirErrors) {
  SynthActorOptions options = Small(4);
  const FaceModel model(options);
  // Named units are taken as given, a jaw unit included.
  options.holdout_units = " AU26_jaw_drop, AU12_lip_corner_puller_L";
  ASSERT_TRUE(options.Check());
  const std::vector<int> held = HeldOutUnits(model, options);
  ASSERT_EQ(held.size(), 2u);
  std::set<std::string> names;
  for (int k : held) names.insert(model.units()[k].name);
  EXPECT_EQ(names, (std::set<std::string>{"AU26_jaw_drop", "AU12_lip_corner_puller_L"}));
  const std::vector<DatasetEntry> plan = PlanDataset(model, options);
  for (const DatasetEntry& entry : plan) EXPECT_FALSE(UsesAny(entry, held)) << entry.name;
  EXPECT_EQ(UnitsNotInDataset(model, plan), held);
  // Other jaw units keep the dataset's jaw motion.
  EXPECT_TRUE(std::any_of(plan.begin(), plan.end(), [&](const DatasetEntry& e) {
    return model.JawPoseOf(e.activations).open_deg > 10;
  }));

  // A count that agrees is fine; one that disagrees is refused.
  options.holdout = 2;
  EXPECT_TRUE(options.Check());
  EXPECT_EQ(HeldOutUnits(model, options), held);
  options.holdout = 3;
  EXPECT_FALSE(options.Check());
  EXPECT_THROW(HeldOutUnits(model, options), InputError);
  options.holdout = 0;
  options.holdout_units = "AU12_lip_corner_puller_L,AU12_lip_corner_puller_L";
  EXPECT_FALSE(options.Check());
  options.holdout_units = "AU99_no_such_unit";
  try {
    HeldOutUnits(model, options, "actor/synth.yaml");
    ADD_FAILURE() << "unknown unit accepted";
  } catch (const InputError& error) {
    EXPECT_NE(std::string(error.what()).find("synth.yaml"), std::string::npos);
    EXPECT_NE(std::string(error.what()).find("AU99_no_such_unit"), std::string::npos);
  }
  options = Small(4);
  options.holdout = -1;
  EXPECT_FALSE(options.Check());
  options.holdout = 100;
  EXPECT_FALSE(options.Check());
}

TEST(SynthActorTest, ResolvedHoldoutRoundTripsThroughSynthYaml) {
  namespace fs = std::filesystem;
  for (int seed : {2, 8}) {
    SynthActorOptions options = Small(seed);
    options.holdout = 4;
    options.dataset_combos = seed % 2 == 0;
    const FaceModel model(options);
    const SynthActorOptions resolved = ResolveHoldout(model, options);
    EXPECT_EQ(resolved.holdout, 4);
    EXPECT_FALSE(resolved.holdout_units.empty());
    EXPECT_EQ(HeldOutUnits(model, resolved), HeldOutUnits(model, options));
    EXPECT_EQ(Names(PlanDataset(model, resolved)), Names(PlanDataset(model, options)));

    const fs::path dir = fs::temp_directory_path() /
                         fmt::format("hmc_synth_holdout_test_{}_{}", getpid(), seed);
    fs::remove_all(dir);
    fs::create_directories(dir);
    WriteSynthActorOptions(resolved, dir);
    const SynthActorOptions read = ReadSynthActorOptions(dir);
    EXPECT_EQ(read.holdout, resolved.holdout);
    EXPECT_EQ(read.holdout_units, resolved.holdout_units);
    // The recorded names win over the seed's draw: another seed's model
    // (same unit catalog) holds out the same units.
    SynthActorOptions other = read;
    other.seed = seed + 100;
    EXPECT_EQ(HeldOutUnits(FaceModel(other), other), HeldOutUnits(model, options));
    fs::remove_all(dir);
  }
}

TEST(SynthActorTest, HoldoutActorIsAValidPackageOfThePlan) {
  SynthActorOptions options = Small(6);
  options.holdout = 5;
  const FaceModel model(options);
  const Actor actor = SynthesizeActorFromModel(model, options);
  EXPECT_NO_THROW(ValidateActor(actor, "synth"));
  const std::vector<DatasetEntry> plan = PlanDataset(model, options);
  ASSERT_EQ(actor.shapes.size(), plan.size());
  for (size_t n = 0; n < plan.size(); ++n) EXPECT_EQ(actor.shapes[n].name, plan[n].name);
  // Markers and the neutral do not depend on the hold-out.
  const Actor full = SynthesizeActorFromModel(model, Small(6));
  EXPECT_EQ(actor.neutral.V, full.neutral.V);
  ASSERT_EQ(actor.markers.size(), full.markers.size());
  for (size_t m = 0; m < actor.markers.size(); ++m) {
    EXPECT_EQ(actor.markers[m].name, full.markers[m].name);
    EXPECT_EQ(actor.markers[m].point.bary, full.markers[m].point.bary);
  }
  EXPECT_LT(actor.shapes.size(), full.shapes.size());
}

}  // namespace
}  // namespace hmc
