#include "synth/synth_actor.h"

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

TEST(SynthActorTest, DeterministicBySeed) {
  const Actor a = SynthesizeActor(Small(5)), b = SynthesizeActor(Small(5));
  const Actor c = SynthesizeActor(Small(6));
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

}  // namespace
}  // namespace hmc
