// calibration.yaml refusals: an incomplete or inconsistent file is refused
// with the file and the key named (core/calibration.h).
#include <cstdlib>
#include <string>

#include <gtest/gtest.h>

#include "core/calibration.h"
#include "core/error.h"
#include "core/file_util.h"
#include "core/temp_dir.h"

namespace hmc {
namespace {

std::string ValidCalibration(const std::filesystem::path& dir) {
  HelmetRig rig;
  FisheyeCamera cam;
  cam.width = 640;
  cam.height = 512;
  cam.fx = cam.fy = 350;
  cam.cx = 320;
  cam.cy = 256;
  for (const char* name : {"cam0", "cam1"}) {
    Rigid3 pose = Rigid3::Identity();
    pose.translation() = Vec3(0, name[3] == '0' ? 20 : -40, -150);
    rig.cameras.push_back({name, cam, pose});
  }
  rig.tags.push_back({3, 22, Rigid3::Identity()});
  WriteCalibration(dir / "valid.yaml", rig);
  return ReadFile(dir / "valid.yaml");
}

// Replaces the n-th occurrence (0-based) of `from` in `text`.
std::string Replace(std::string text, const std::string& from, const std::string& to,
                    int n = 0) {
  size_t pos = text.find(from);
  for (int i = 0; i < n && pos != std::string::npos; ++i) pos = text.find(from, pos + 1);
  EXPECT_NE(pos, std::string::npos) << from;
  if (pos != std::string::npos) text.replace(pos, from.size(), to);
  return text;
}

void ExpectRefused(const std::filesystem::path& dir, const std::string& text,
                   const std::string& key) {
  const auto path = dir / "broken_calibration.yaml";
  WriteFileAtomic(path, text);
  try {
    ReadCalibration(path);
    ADD_FAILURE() << "accepted a calibration with a bad " << key;
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("broken_calibration.yaml"), std::string::npos) << what;
    EXPECT_NE(what.find(key), std::string::npos) << what;
  }
}

// Issue 24, item 10: a key given twice (FileStorage alone keeps one of
// them) is refused with its line, at the top level and inside a camera.
TEST(CalibrationValidationTest, RepeatedKeysAreRefused) {
  TempDir dir;
  const std::string valid = ValidCalibration(dir.path());
  ASSERT_NE(valid.find("units: mm\n"), std::string::npos) << valid;
  ExpectRefused(dir.path(), Replace(valid, "units: mm\n", "units: mm\nunits: cm\n"),
                "given twice");
  ASSERT_NE(valid.find("image_width: 640\n"), std::string::npos) << valid;
  const size_t at = valid.find("image_width: 640\n");
  const size_t line_start = valid.rfind('\n', at) + 1;
  const std::string indent = valid.substr(line_start, at - line_start);
  ExpectRefused(dir.path(),
                Replace(valid, "image_width: 640\n",
                        "image_width: 640\n" + indent + "image_width: 64\n"),
                "given twice");
}

// Found by fuzzing (docs/reliability.md): a matrix node OpenCV cannot read
// (no usable `dt`) threw a raw cv::Exception; it is an InputError.
TEST(CalibrationValidationTest, FuzzedMalformedMatrixIsAnInputError) {
  const char* root = std::getenv("HMC_SOURCE_DIR");
  const std::filesystem::path file = std::filesystem::path(root ? root : ".") /
                                     "tests/fixtures/fuzz_crashes/calibration_matrix_without_dt.yaml";
  ASSERT_TRUE(std::filesystem::exists(file));
  EXPECT_THROW(ReadCalibration(file), InputError);
}

// Found by fuzzing: text on which OpenCV's FileStorage parser loops
// forever (the file is read with yaml-cpp now, core/calibration.h). A
// return to that parser would hang this test until its timeout.
TEST(CalibrationValidationTest, FuzzedTextThatHungOpenCvIsRefused) {
  const char* root = std::getenv("HMC_SOURCE_DIR");
  const std::filesystem::path file = std::filesystem::path(root ? root : ".") /
                                     "tests/fixtures/fuzz_crashes/calibration_hangs_opencv_parser.yaml";
  ASSERT_TRUE(std::filesystem::exists(file));
  EXPECT_THROW(ReadCalibration(file), InputError);
}

// A matrix node holding a huge size or too few numbers is refused before
// any allocation, naming the key.
TEST(CalibrationValidationTest, MatrixSizesAreCheckedAgainstTheirData) {
  TempDir dir;
  const std::string valid = ValidCalibration(dir.path());
  ExpectRefused(dir.path(), Replace(valid, "rows: 3", "rows: 1000000000"), "cameras[0].K.rows");
  ExpectRefused(dir.path(), Replace(valid, "cols: 3", "cols: 4"), "cameras[0].K.data");
  ExpectRefused(dir.path(), Replace(valid, "image_width: 640", "image_width: 1e80"),
                "cameras[0].image_width");
}

TEST(CalibrationValidationTest, BadFilesAreRefusedNamingTheKey) {
  TempDir dir;
  const std::string valid = ValidCalibration(dir.path());
  ASSERT_EQ(ReadCalibration(dir.path() / "valid.yaml").cameras.size(), 2u);
  ExpectRefused(dir.path(), Replace(valid, "image_width", "image_wide", 1),
                "cameras[1].image_width");
  ExpectRefused(dir.path(), Replace(valid, "cam_from_helmet:", "cam_to_helmet:", 0),
                "cameras[0].cam_from_helmet");
  ExpectRefused(dir.path(), Replace(valid, "name: cam1", "nom: cam1"), "cameras[1].name");
  ExpectRefused(dir.path(), Replace(valid, "tag_family", "tag_familly"), "tag_family");
  ExpectRefused(dir.path(), Replace(valid, "size: 22", "size: -1"), "tags[0].size");
  // A scaled rotation (not a rigid transform) in cam1's pose: its first
  // element 1. -> 1.1.
  const size_t pose = valid.find("cam_from_helmet", valid.find("name: cam1"));
  const size_t data = valid.find("data: [ 1.", pose);
  ASSERT_NE(data, std::string::npos);
  std::string scaled = valid;
  scaled.replace(data, std::string("data: [ 1.").size(), "data: [ 1.1");
  ExpectRefused(dir.path(), scaled, "cameras[1].cam_from_helmet");
}

// Issue 45, item 2: two cameras of one name would both read that camera's
// footage; refused when the file is read, naming the second camera.
TEST(CalibrationValidationTest, DuplicateCameraNamesAreRefused) {
  TempDir dir;
  const std::string valid = ValidCalibration(dir.path());
  ExpectRefused(dir.path(), Replace(valid, "name: cam1", "name: cam0"),
                "'cameras[1].name' cam0 is also cameras[0]'s name");
}

// Issue 44, item 5: the lens model is read, not assumed. A model hmc does
// not support, or none, is refused naming the file, the camera and the model.
TEST(CalibrationValidationTest, UnsupportedOrMissingLensModelIsRefused) {
  TempDir dir;
  const std::string valid = ValidCalibration(dir.path());
  ASSERT_NE(valid.find("model: kannala_brandt"), std::string::npos) << valid;
  const std::string unsupported = Replace(valid, "model: kannala_brandt", "model: unified_omni", 1);
  ExpectRefused(dir.path(), unsupported, "cam1");
  ExpectRefused(dir.path(), unsupported, "unified_omni");
  ExpectRefused(dir.path(), unsupported, "cameras[1].model");
  ExpectRefused(dir.path(), Replace(valid, "model: kannala_brandt", "modle: kannala_brandt"),
                "cameras[0].model");
}

}  // namespace
}  // namespace hmc
