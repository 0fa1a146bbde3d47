#include "pipeline/run_pipeline.h"

#include <algorithm>
#include <map>
#include <stdexcept>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "core/actor.h"
#include "core/calibration.h"
#include "core/error.h"
#include "core/file_util.h"
#include "core/hash.h"
#include "core/temp_dir.h"
#include "synth/synth_actor.h"

namespace hmc {
namespace {

namespace fs = std::filesystem;

// A stand-in for the hmc commands: each writes its outputs with content
// made of its command name and the bytes of every existing file among its
// arguments, so an output changes exactly when an input does.
class FakeCommands {
 public:
  int operator()(const std::vector<std::string>& args) {
    calls.push_back(args[0]);
    args_of[args[0]] = args;
    if (args[0] == fail_on) throw std::runtime_error("killed in " + fail_on);
    std::string content = args[0];
    for (const std::string& a : args) {
      std::error_code ec;
      if (fs::is_regular_file(a, ec)) content += "|" + HashHex(HashFile(a));
    }
    const auto flag = [&](const std::string& name) {
      for (size_t i = 0; i + 1 < args.size(); ++i) {
        if (args[i] == name) return fs::path(args[i + 1]);
      }
      return fs::path();
    };
    if (args[0] == "stabilize") {
      WriteFileAtomic(flag("--out") / "bundles.csv", content);
      WriteFileAtomic(flag("--out") / "head_from_helmet.csv", content);
    } else if (args[0] == "report") {
      WriteFileAtomic(flag("--out") / "report.html", content);
    } else if (args[0] == "convert") {
      WriteFileAtomic(args[2], content);
    } else {
      WriteFileAtomic(flag("--out"), content);
      if (!flag("--topology").empty()) WriteFileAtomic(flag("--topology"), "topology");
    }
    return 0;
  }
  std::vector<std::string> calls;
  std::map<std::string, std::vector<std::string>> args_of;  // the last call's
  std::string fail_on;
};

struct Fixture {
  TempDir dir;
  RunInput input;
  explicit Fixture(const std::string& actor_rig = "generator", bool tags = true) {
    SynthActorOptions actor;
    actor.rig = actor_rig;
    actor.grid_u = 24;
    actor.grid_v = 20;
    actor.dataset_inbetweens = false;
    actor.dataset_combos = false;
    WriteActor(SynthesizeActor(actor), dir.path() / "actor", 17);
    HelmetRig rig;
    for (const char* name : {"cam0", "cam1"}) {
      HelmetCamera c;
      c.name = name;
      c.camera.width = 32;
      c.camera.height = 24;
      c.camera.fx = c.camera.fy = 20;
      c.camera.cx = 16;
      c.camera.cy = 12;
      c.cam_from_helmet = Rigid3::Identity();
      rig.cameras.push_back(c);
      fs::create_directories(dir.path() / "shot" / name);
      for (int f = 1; f <= 3; ++f) {
        cv::imwrite((dir.path() / "shot" / name / fmt::format("frame_{:06d}.png", f)).string(),
                    cv::Mat(24, 32, CV_8U, cv::Scalar(10 * f)));
      }
    }
    if (tags) {
      HelmetTag tag;
      tag.size = 20;
      tag.helmet_from_tag = Rigid3::Identity();
      rig.tags.push_back(tag);
    }
    WriteCalibration(dir.path() / "calibration.yaml", rig);
    input.shot = (dir.path() / "shot").string();
    input.actor = (dir.path() / "actor").string();
    input.calibration = (dir.path() / "calibration.yaml").string();
    input.out = (dir.path() / "work").string();
  }
  std::map<std::string, std::string> Outputs() const {
    std::map<std::string, std::string> files;
    for (const auto& e : fs::recursive_directory_iterator(input.out)) {
      if (e.is_regular_file() && e.path().filename() != "summary.json") {
        files[fs::relative(e.path(), input.out).string()] = ReadFile(e.path());
      }
    }
    return files;
  }
};

std::vector<std::string> Statuses(const RunSummary& s) {
  std::vector<std::string> out;
  for (const StageRun& r : s.stages) out.push_back(r.stage + ":" + r.status);
  return out;
}

TEST(RunPipelineTest, RunsEveryStageOnceThenKeepsWhatIsComplete) {
  Fixture fx;
  FakeCommands commands;
  const RunSummary first = RunPipeline(fx.input, RunOptions{}, std::ref(commands));
  EXPECT_EQ(commands.calls,
            (std::vector<std::string>{"calibrate", "track", "triangulate", "stabilize", "jaw",
                                      "solve", "report"}));
  for (const std::string& stage : PipelineStages()) {
    EXPECT_TRUE(fs::is_regular_file(fs::path(fx.input.out) / stage / "summary.json")) << stage;
  }
  commands.calls.clear();
  const RunSummary second = RunPipeline(fx.input, RunOptions{}, std::ref(commands));
  EXPECT_TRUE(commands.calls.empty());
  for (const StageRun& r : second.stages) EXPECT_EQ(r.status, "complete") << r.stage;
}

// An actor as most studios have it, without a jaw rig (the linear rig):
// the jaw stage records that it was skipped and the solve gets no --jaw.
TEST(RunPipelineTest, AnActorWithoutAJawRigSkipsTheJawStage) {
  Fixture fx("linear");
  FakeCommands commands;
  const RunSummary s = RunPipeline(fx.input, RunOptions{}, std::ref(commands));
  EXPECT_EQ(commands.calls,
            (std::vector<std::string>{"calibrate", "track", "triangulate", "stabilize", "solve",
                                      "report"}));
  EXPECT_EQ(Statuses(s)[4], "jaw:skipped");
  const nlohmann::json summary = nlohmann::json::parse(
      ReadFile(fs::path(fx.input.out) / "jaw" / "summary.json"));
  EXPECT_NE(summary.dump().find("no jaw rig"), std::string::npos) << summary.dump();
  const std::vector<std::string>& solve = commands.args_of.at("solve");
  EXPECT_EQ(std::find(solve.begin(), solve.end(), "--jaw"), solve.end());
  // Complete once skipped: a second run keeps every stage.
  commands.calls.clear();
  RunPipeline(fx.input, RunOptions{}, std::ref(commands));
  EXPECT_TRUE(commands.calls.empty());
}

// Most helmets carry no tags: their rig is the pair's stereo calibration,
// used as it is with no option changed (issue 44).
TEST(RunPipelineTest, AHelmetWithoutTagsUsesItsCalibrationAsItIs) {
  Fixture fx("generator", /*tags=*/false);
  FakeCommands commands;
  const RunSummary s = RunPipeline(fx.input, RunOptions{}, std::ref(commands));
  EXPECT_EQ(commands.calls.front(), "track");
  EXPECT_EQ(std::count(commands.calls.begin(), commands.calls.end(), "calibrate"), 0);
  EXPECT_EQ(ReadFile(fs::path(fx.input.out) / "calibrate" / "calibration.yaml"),
            ReadFile(fx.input.calibration));
  const nlohmann::json summary = nlohmann::json::parse(
      ReadFile(fs::path(fx.input.out) / "calibrate" / "summary.json"));
  EXPECT_NE(summary.dump().find("no tags"), std::string::npos) << summary.dump();
}

TEST(RunPipelineTest, AChangedInputOrOptionRedoesItsStageAndWhatDependsOnIt) {
  Fixture fx;
  FakeCommands commands;
  RunPipeline(fx.input, RunOptions{}, std::ref(commands));
  // A new option of the triangulation: calibrate and track are kept.
  WriteFileAtomic(fx.dir.path() / "run.yaml", "triangulate:\n  gate_px: 3\n");
  fx.input.config = (fx.dir.path() / "run.yaml").string();
  commands.calls.clear();
  RunPipeline(fx.input, RunOptions{}, std::ref(commands));
  EXPECT_EQ(commands.calls, (std::vector<std::string>{"triangulate", "stabilize", "jaw", "solve",
                                                      "report"}));
  EXPECT_TRUE(fs::exists(fs::path(fx.input.out) / "triangulate" / "run_config.yaml"));
  // New footage: the stages that read it are redone; the fake's outputs
  // do not depend on the pixels, so the stages after them are kept (the
  // keys are contents, not times), and the report is redone.
  cv::imwrite(fs::path(fx.input.shot) / "cam1" / "frame_000002.png", cv::Mat(24, 32, CV_8U, cv::Scalar(99)));
  commands.calls.clear();
  RunPipeline(fx.input, RunOptions{}, std::ref(commands));
  EXPECT_EQ(commands.calls, (std::vector<std::string>{"calibrate", "track", "report"}));
}

// An image sequence declares no frame rate: the caches are written at the
// commands' default unless the run says otherwise (a 60 fps helmet's PNG
// sequence must not come out at 30); a new rate redoes the solve only.
TEST(RunPipelineTest, TheRunsFrameRateReachesTheSolveAndTheExports) {
  Fixture fx;
  FakeCommands commands;
  RunOptions usda;  // the default exports none beside mesh.pc2 (issue 46)
  usda.export_formats = "usda";
  RunPipeline(fx.input, usda, std::ref(commands));
  const std::vector<std::string>& solve = commands.args_of.at("solve");
  EXPECT_EQ(std::find(solve.begin(), solve.end(), "--fps"), solve.end());
  // The exports get the default rate spelt out (convert warns without one).
  const std::vector<std::string>& convert = commands.args_of.at("convert");
  const auto rate = std::find(convert.begin(), convert.end(), "--fps");
  ASSERT_NE(rate, convert.end());
  ASSERT_NE(rate + 1, convert.end());
  EXPECT_EQ(*(rate + 1), "30");
  RunOptions options = usda;
  options.fps = 60;
  commands.calls.clear();
  RunPipeline(fx.input, options, std::ref(commands));
  EXPECT_EQ(commands.calls, (std::vector<std::string>{"solve", "convert", "report"}));
  for (const char* command : {"solve", "convert"}) {
    const std::vector<std::string>& args = commands.args_of.at(command);
    const auto it = std::find(args.begin(), args.end(), "--fps");
    ASSERT_NE(it, args.end()) << command;
    ASSERT_NE(it + 1, args.end()) << command;
    EXPECT_EQ(*(it + 1), "60") << command;
  }
  options.fps = -1;
  EXPECT_FALSE(options.Check());
}

// Issue 46: footage is one continuous recording, so the run's solve treats
// its frames as a take (--robust.take yes) unless the run config's solve
// section decides; the diagnostics' detail reaches the solve, and a change
// of it redoes the solve (and the report) only.
TEST(RunPipelineTest, TheSolveTreatsFootageAsATakeUnlessTheConfigDecides) {
  Fixture fx;
  FakeCommands commands;
  RunPipeline(fx.input, RunOptions{}, std::ref(commands));
  auto value_of = [&](const std::string& flag) {
    const std::vector<std::string>& solve = commands.args_of.at("solve");
    const auto it = std::find(solve.begin(), solve.end(), flag);
    return it == solve.end() || it + 1 == solve.end() ? std::string("(none)") : *(it + 1);
  };
  EXPECT_EQ(value_of("--robust.take"), "yes");
  EXPECT_EQ(value_of("--diagnostics_detail"), "summary");
  RunOptions full;
  full.diagnostics = "full";
  commands.calls.clear();
  RunPipeline(fx.input, full, std::ref(commands));
  EXPECT_EQ(commands.calls, (std::vector<std::string>{"solve", "report"}));
  EXPECT_EQ(value_of("--diagnostics_detail"), "full");
  WriteFileAtomic(fx.dir.path() / "run.yaml", "solve:\n  robust:\n    take: auto\n");
  fx.input.config = (fx.dir.path() / "run.yaml").string();
  RunPipeline(fx.input, full, std::ref(commands));
  EXPECT_EQ(value_of("--robust.take"), "(none)");
}

// Issue 52: what every stage that reads the footage shares is set once for
// the run and reaches each of them; in a stage's section it is refused,
// naming where it moved; every section is checked before any stage runs.
TEST(RunPipelineTest, FootageOptionsAreSetOnceForTheRunAndSectionsCheckedFirst) {
  Fixture fx;
  FakeCommands commands;
  RunOptions options;
  options.footage.offset1 = 2;
  options.footage.frames = "1:2";
  options.reference_frame = 2;
  RunPipeline(fx.input, options, std::ref(commands));
  auto value_of = [&](const char* command, const std::string& flag) -> std::string {
    const std::vector<std::string>& args = commands.args_of.at(command);
    const auto it = std::find(args.begin(), args.end(), flag);
    return it == args.end() || it + 1 == args.end() ? "" : *(it + 1);
  };
  for (const char* command : {"calibrate", "track"}) {
    EXPECT_EQ(value_of(command, "--offset1"), "2") << command;
    EXPECT_EQ(value_of(command, "--frames"), "1:2") << command;
  }
  EXPECT_EQ(value_of("track", "--reference_frame"), "2");

  for (const std::string config : {"track:\n  offset1: 1\n", "calibrate:\n  frames: 1:2\n",
                                   "track:\n  reference_frame: 3\n"}) {
    Fixture f;
    FakeCommands none;
    WriteFileAtomic(f.dir.path() / "run.yaml", config);
    f.input.config = (f.dir.path() / "run.yaml").string();
    try {
      RunPipeline(f.input, RunOptions{}, std::ref(none));
      ADD_FAILURE() << config;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("run.yaml:2"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("give it as run."), std::string::npos) << e.what();
    }
    EXPECT_TRUE(none.calls.empty());
  }

  // The checker sees every stage's section before the first stage runs.
  Fixture f;
  FakeCommands none;
  WriteFileAtomic(f.dir.path() / "run.yaml", "track:\n  threads: 1\nsolve:\n  bad: 1\n");
  f.input.config = (f.dir.path() / "run.yaml").string();
  std::vector<std::string> checked;
  f.input.check_section = [&](const std::string& stage, const YAML::Node&, const fs::path& file) {
    EXPECT_TRUE(none.calls.empty());
    checked.push_back(stage);
    if (stage == "solve") ThrowInputError(file, 4, "unknown option 'bad'");
  };
  EXPECT_THROW(RunPipeline(f.input, RunOptions{}, std::ref(none)), InputError);
  EXPECT_EQ(checked, (std::vector<std::string>{"track", "solve"}));
  EXPECT_TRUE(none.calls.empty());
}

TEST(RunPipelineTest, FromAndToChooseTheStages) {
  Fixture fx;
  FakeCommands commands;
  RunOptions options;
  options.to = "triangulate";
  const RunSummary s = RunPipeline(fx.input, options, std::ref(commands));
  EXPECT_EQ(commands.calls, (std::vector<std::string>{"calibrate", "track", "triangulate"}));
  EXPECT_EQ(Statuses(s).back(), "report:not run");
  commands.calls.clear();
  options.to = "report";
  options.from = "track";
  RunPipeline(fx.input, options, std::ref(commands));
  EXPECT_EQ(commands.calls.front(), "track");  // calibrate kept, track forced
  EXPECT_EQ(commands.calls.size(), 6u);
}

TEST(RunPipelineTest, AnInterruptedRunResumesToTheSameOutputs) {
  Fixture whole;
  FakeCommands commands;
  RunPipeline(whole.input, RunOptions{}, std::ref(commands));
  const auto expected = whole.Outputs();

  Fixture fx;
  FakeCommands failing;
  failing.fail_on = "stabilize";
  EXPECT_THROW(RunPipeline(fx.input, RunOptions{}, std::ref(failing)), std::runtime_error);
  EXPECT_FALSE(fs::exists(fs::path(fx.input.out) / "stabilize"));
  FakeCommands resumed;
  RunPipeline(fx.input, RunOptions{}, std::ref(resumed));
  EXPECT_EQ(resumed.calls.front(), "stabilize");
  // Same bytes as the uninterrupted run's (the fake's content holds hashes
  // of the inputs, not paths), and nothing partial or temporary left.
  const auto got = fx.Outputs();
  ASSERT_EQ(got.size(), expected.size());
  for (const auto& [name, content] : expected) EXPECT_EQ(got.at(name), content) << name;
  for (const auto& e : fs::recursive_directory_iterator(fx.input.out)) {
    const std::string name = e.path().filename().string();
    if (name == ".hmc_workspace" || name == ".hmc_lock") continue;  // the workspace's own
    EXPECT_NE(name.front(), '.') << e.path();
  }
}

TEST(RunPipelineTest, BadRunConfigsAreRefusedWithTheFile) {
  Fixture fx;
  FakeCommands commands;
  WriteFileAtomic(fx.dir.path() / "run.yaml", "trak:\n  x: 1\n");
  fx.input.config = (fx.dir.path() / "run.yaml").string();
  try {
    RunPipeline(fx.input, RunOptions{}, std::ref(commands));
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("run.yaml:1"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("trak"), std::string::npos);
  }
  EXPECT_TRUE(commands.calls.empty());
  RunOptions bad;
  bad.from = "solve";
  bad.to = "track";
  EXPECT_FALSE(bad.Check());
  bad.from = "nope";
  EXPECT_FALSE(bad.Check());
}

}  // namespace
}  // namespace hmc
