#include "core/mesh_sequence.h"

#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <stdexcept>
#include <string>

#include <gtest/gtest.h>

#include "core/temp_dir.h"

#include "core/error.h"
#include "core/file_util.h"

namespace hmc {
namespace {

namespace fs = std::filesystem;

int CountEntries(const fs::path& dir) {
  return static_cast<int>(
      std::distance(fs::directory_iterator(dir), fs::directory_iterator()));
}

// A random sequence on a small grid mesh with a UV per triangle corner (so
// UV indices differ from vertex indices). `float_exact`: every value is a
// float32, so the float32 formats must reproduce it bit for bit.
MeshSequence RandomSequence(unsigned seed, int num_frames, bool float_exact) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> coordinate(-150.0, 150.0);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  auto value = [&](double x) {
    return float_exact ? static_cast<double>(static_cast<float>(x)) : x;
  };
  const int cols = 3 + static_cast<int>(seed % 3);
  const int rows = 4;
  MeshSequence seq;
  seq.start_frame = static_cast<int>(seed % 7) - 2;  // negative, zero, positive
  seq.fps = 24.0;
  TriMesh& mesh = seq.topology;
  mesh.F.resize(2 * (cols - 1) * (rows - 1), 3);
  int t = 0;
  for (int r = 0; r + 1 < rows; ++r) {
    for (int c = 0; c + 1 < cols; ++c) {
      const int v = r * cols + c;
      mesh.F.row(t++) << v, v + 1, v + cols + 1;
      mesh.F.row(t++) << v, v + cols + 1, v + cols;
    }
  }
  mesh.UV.resize(3 * mesh.NumFaces(), 2);
  mesh.FUV.resize(mesh.NumFaces(), 3);
  for (int i = 0; i < mesh.UV.rows(); ++i) {
    mesh.UV(i, 0) = value(unit(rng));
    mesh.UV(i, 1) = value(unit(rng));
    mesh.FUV(i / 3, i % 3) = i;
  }
  for (int f = 0; f < num_frames; ++f) {
    MatX3d X(rows * cols, 3);
    for (int i = 0; i < X.size(); ++i) X.data()[i] = value(coordinate(rng));
    seq.frames.push_back(X);
  }
  mesh.V = seq.frames[0];
  return seq;
}

void ExpectSameFrames(const MeshSequence& a, const MeshSequence& b) {
  ASSERT_EQ(a.frames.size(), b.frames.size());
  for (size_t f = 0; f < a.frames.size(); ++f) {
    ASSERT_EQ(a.frames[f].rows(), b.frames[f].rows());
    EXPECT_TRUE(a.frames[f] == b.frames[f]) << "frame " << f;
  }
}

void ExpectSameTopology(const TriMesh& a, const TriMesh& b) {
  EXPECT_TRUE(a.F == b.F);
  EXPECT_TRUE(a.UV == b.UV);
  EXPECT_TRUE(a.FUV == b.FUV);
}

// Runs `read` and expects an InputError that names `file`.
template <typename Fn>
void ExpectInputErrorNaming(const fs::path& file, Fn read,
                            const std::string& message_part = "") {
  try {
    read();
    ADD_FAILURE() << "no error for " << file;
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(file.string()), std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find(message_part), std::string::npos)
        << e.what();
  }
}

std::string Bytes(const fs::path& file) { return ReadFile(file); }

void Truncate(const fs::path& file, int64_t drop_bytes) {
  fs::resize_file(file, fs::file_size(file) - drop_bytes);
}

class MeshSequenceSeeded : public ::testing::TestWithParam<unsigned> {};

TEST_P(MeshSequenceSeeded, Pc2RoundTripIsExact) {
  const TempDir temp_dir("hmc_mesh_sequence_" + std::string("pc2_" + std::to_string(GetParam())));
  const fs::path& dir = temp_dir.path();
  const MeshSequence seq = RandomSequence(GetParam(), 5, true);
  WriteMeshSequence(dir / "seq.pc2", seq);
  const MeshSequence back = ReadMeshSequence(dir / "seq.pc2");
  ExpectSameFrames(seq, back);
  EXPECT_EQ(back.start_frame, seq.start_frame);
  EXPECT_EQ(back.fps, 30.0);  // PC2 carries no frame rate
  EXPECT_EQ(back.topology.NumFaces(), 0);

  MeshSequenceReadOptions options;
  options.topology = &seq.topology;
  options.fps = 24.0;
  const MeshSequence with_topology = ReadMeshSequence(dir / "seq.pc2", options);
  EXPECT_EQ(with_topology.fps, 24.0);
  ExpectSameTopology(with_topology.topology, seq.topology);
}

TEST_P(MeshSequenceSeeded, Pc2HeaderMatchesBlendersLayout) {
  const TempDir temp_dir("hmc_mesh_sequence_" + std::string("pc2_header_" + std::to_string(GetParam())));
  const fs::path& dir = temp_dir.path();
  const MeshSequence seq = RandomSequence(GetParam(), 3, true);
  WriteMeshSequence(dir / "seq.pc2", seq);
  const std::string bytes = Bytes(dir / "seq.pc2");
  const int num_points = static_cast<int>(seq.frames[0].rows());
  ASSERT_EQ(bytes.size(), 32u + 3u * num_points * 12u);
  EXPECT_EQ(std::memcmp(bytes.data(), "POINTCACHE2\0", 12), 0);
  // This host is little endian, like the file: plain copies decode it.
  int32_t version, points, samples;
  float start, rate, x0;
  std::memcpy(&version, bytes.data() + 12, 4);
  std::memcpy(&points, bytes.data() + 16, 4);
  std::memcpy(&start, bytes.data() + 20, 4);
  std::memcpy(&rate, bytes.data() + 24, 4);
  std::memcpy(&samples, bytes.data() + 28, 4);
  std::memcpy(&x0, bytes.data() + 32 + 12 * num_points + 4, 4);
  EXPECT_EQ(version, 1);
  EXPECT_EQ(points, num_points);
  EXPECT_EQ(start, static_cast<float>(seq.start_frame));
  EXPECT_EQ(rate, 1.0f);
  EXPECT_EQ(samples, 3);
  EXPECT_EQ(x0, static_cast<float>(seq.frames[1](0, 1)));  // sample 1, y
}

TEST_P(MeshSequenceSeeded, MddRoundTripKeepsFramesFpsAndStart) {
  const TempDir temp_dir("hmc_mesh_sequence_" + std::string("mdd_" + std::to_string(GetParam())));
  const fs::path& dir = temp_dir.path();
  for (const double fps : {24.0, 25.0, 30.0, 60.0, 30000.0 / 1001.0}) {
    MeshSequence seq = RandomSequence(GetParam(), 4, true);
    seq.fps = fps;
    WriteMeshSequence(dir / "seq.mdd", seq);
    const MeshSequence back = ReadMeshSequence(dir / "seq.mdd");
    ExpectSameFrames(seq, back);
    EXPECT_EQ(back.start_frame, seq.start_frame) << fps;
    EXPECT_NEAR(back.fps, fps, 1e-9 * fps);

    // Header: big-endian counts, then times (start + i) / fps in seconds.
    const std::string bytes = Bytes(dir / "seq.mdd");
    auto big_u32 = [&](size_t at) {
      uint32_t v = 0;
      for (int i = 0; i < 4; ++i) {
        v = (v << 8) | static_cast<unsigned char>(bytes[at + i]);
      }
      return v;
    };
    const int num_points = static_cast<int>(seq.frames[0].rows());
    ASSERT_EQ(bytes.size(), 8u + 4u * 4u + 4u * num_points * 12u);
    EXPECT_EQ(big_u32(0), 4u);
    EXPECT_EQ(big_u32(4), static_cast<uint32_t>(num_points));
    for (int f = 0; f < 4; ++f) {
      const uint32_t bits = big_u32(8 + 4 * f);
      float time_s;
      std::memcpy(&time_s, &bits, 4);
      EXPECT_EQ(time_s, static_cast<float>((seq.start_frame + f) / fps));
    }
  }
}

TEST_P(MeshSequenceSeeded, UsdaRoundTripIsExactInFloat32) {
  const TempDir temp_dir("hmc_mesh_sequence_" + std::string("usda_" + std::to_string(GetParam())));
  const fs::path& dir = temp_dir.path();
  // point3f / texCoord2f are float32: float32 values come back bit for bit,
  // doubles come back rounded to float32 (as every USD reader sees them).
  for (const bool float_exact : {true, false}) {
    MeshSequence seq = RandomSequence(GetParam(), 3, float_exact);
    seq.fps = 30000.0 / 1001.0;
    WriteMeshSequence(dir / "seq.usda", seq);
    const MeshSequence back = ReadMeshSequence(dir / "seq.usda");
    MeshSequence expected = seq;
    for (MatX3d& X : expected.frames) X = X.cast<float>().cast<double>();
    expected.topology.UV = seq.topology.UV.cast<float>().cast<double>();
    ExpectSameFrames(expected, back);
    ExpectSameTopology(back.topology, expected.topology);
    EXPECT_EQ(back.start_frame, seq.start_frame);
    EXPECT_EQ(back.fps, seq.fps);
  }
}

TEST_P(MeshSequenceSeeded, ObjFolderRoundTripIsExact) {
  const TempDir temp_dir("hmc_mesh_sequence_" + std::string("obj_" + std::to_string(GetParam())));
  const fs::path& dir = temp_dir.path();
  const MeshSequence seq = RandomSequence(GetParam(), 3, false);
  WriteMeshSequence(dir / "frames", seq, 17);
  EXPECT_EQ(CountEntries(dir / "frames"), 3);
  EXPECT_TRUE(fs::exists(dir / "frames" /
                         fmt::format("frame_{:06d}.obj", seq.start_frame + 2)));
  EXPECT_EQ(CountEntries(dir), 1);  // no temporary folder left behind
  MeshSequenceReadOptions options;
  options.fps = 24.0;
  const MeshSequence back = ReadMeshSequence(dir / "frames", options);
  ExpectSameFrames(seq, back);
  ExpectSameTopology(back.topology, seq.topology);
  EXPECT_EQ(back.start_frame, seq.start_frame);
  EXPECT_EQ(back.fps, 24.0);

  // Rewriting replaces the folder: frames of the old sequence are gone.
  MeshSequence shorter = RandomSequence(GetParam() + 100, 2, false);
  shorter.start_frame = seq.start_frame + 10;
  WriteMeshSequence(dir / "frames/", shorter, 17);
  EXPECT_EQ(CountEntries(dir / "frames"), 2);
  ExpectSameFrames(shorter, ReadMeshSequence(dir / "frames"));
  EXPECT_EQ(CountEntries(dir), 1);
}

TEST_P(MeshSequenceSeeded, FormatsConvertIntoEachOther) {
  const TempDir temp_dir("hmc_mesh_sequence_" + std::string("chain_" + std::to_string(GetParam())));
  const fs::path& dir = temp_dir.path();
  const MeshSequence seq = RandomSequence(GetParam(), 4, true);
  // pc2 -> mdd -> usda -> obj folder -> pc2: float32 values survive all.
  WriteMeshSequence(dir / "a.pc2", seq);
  MeshSequenceReadOptions options;
  options.topology = &seq.topology;
  options.fps = seq.fps;
  WriteMeshSequence(dir / "b.mdd", ReadMeshSequence(dir / "a.pc2", options));
  options.fps = 0;
  WriteMeshSequence(dir / "c.usda", ReadMeshSequence(dir / "b.mdd", options));
  WriteMeshSequence(dir / "d", ReadMeshSequence(dir / "c.usda"));
  MeshSequenceReadOptions obj_options;
  obj_options.fps = seq.fps;
  WriteMeshSequence(dir / "e.pc2", ReadMeshSequence(dir / "d", obj_options));
  const MeshSequence back = ReadMeshSequence(dir / "e.pc2");
  ExpectSameFrames(seq, back);
  EXPECT_EQ(back.start_frame, seq.start_frame);
  EXPECT_EQ(Bytes(dir / "a.pc2"), Bytes(dir / "e.pc2"));
}

// Reading a few frames of a sequence: those frames as a full read gives
// them, the others empty, the numbering kept; in every format.
TEST_P(MeshSequenceSeeded, WantedFramesOnlyAreRead) {
  const TempDir temp_dir("hmc_mesh_sequence_" + std::string("wanted_" + std::to_string(GetParam())));
  const fs::path& dir = temp_dir.path();
  const MeshSequence seq = RandomSequence(GetParam(), 6, true);
  WriteMeshSequence(dir / "s.pc2", seq);
  WriteMeshSequence(dir / "s.mdd", seq);
  WriteMeshSequence(dir / "s.usda", seq);
  const int a = seq.start_frame + 1, b = seq.start_frame + 4;
  for (const char* name : {"s.pc2", "s.mdd", "s.usda"}) {
    SCOPED_TRACE(name);
    MeshSequenceReadOptions options;
    options.topology = &seq.topology;
    options.fps = seq.fps;
    const MeshSequence all = ReadMeshSequence(dir / name, options);
    options.wanted = [a, b](int f) { return f == a || f == b; };
    const MeshSequence some = ReadMeshSequence(dir / name, options);
    ASSERT_EQ(some.frames.size(), all.frames.size());
    EXPECT_EQ(some.start_frame, all.start_frame);
    for (size_t f = 0; f < all.frames.size(); ++f) {
      const int number = all.start_frame + static_cast<int>(f);
      if (number == a || number == b) {
        EXPECT_EQ(some.frames[f], all.frames[f]) << number;
      } else {
        EXPECT_EQ(some.frames[f].rows(), 0) << number;
      }
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Seeds, MeshSequenceSeeded,
                         ::testing::Values(1u, 2u, 3u, 11u, 42u));

TEST(MeshSequenceTest, UsdaHasTheMetadataDccsNeed) {
  const TempDir temp_dir("hmc_mesh_sequence_" + std::string("usda_meta"));
  const fs::path& dir = temp_dir.path();
  MeshSequence seq = RandomSequence(5, 2, true);
  seq.start_frame = 101;
  WriteMeshSequence(dir / "seq.usda", seq);
  const std::string text = Bytes(dir / "seq.usda");
  for (const char* expected :
       {"#usda 1.0", "upAxis = \"Y\"", "metersPerUnit = 0.001",
        "startTimeCode = 101", "endTimeCode = 102",
        "timeCodesPerSecond = 24", "framesPerSecond = 24",
        "point3f[] points.timeSamples", "101: [", "102: [",
        "texCoord2f[] primvars:st", "interpolation = \"faceVarying\"",
        "int[] primvars:st:indices", "int[] faceVertexCounts",
        "int[] faceVertexIndices", "defaultPrim = \"face\""}) {
    EXPECT_NE(text.find(expected), std::string::npos) << expected;
  }
  // Without a timecode none is written; with one, it reads back (and the
  // formats without a place for it drop it).
  EXPECT_EQ(text.find("timecode"), std::string::npos);
  EXPECT_EQ(ReadMeshSequence(dir / "seq.usda").timecode, "");
  seq.timecode = "01:00:03;02";
  WriteMeshSequence(dir / "tc.usda", seq);
  EXPECT_NE(Bytes(dir / "tc.usda").find("string timecode = \"01:00:03;02\""), std::string::npos);
  const MeshSequence back = ReadMeshSequence(dir / "tc.usda");
  EXPECT_EQ(back.timecode, seq.timecode);
  EXPECT_EQ(back.start_frame, 101);
  WriteMeshSequence(dir / "tc.pc2", seq);
  EXPECT_EQ(ReadMeshSequence(dir / "tc.pc2").timecode, "");
  fs::remove_all(dir);
}

TEST(MeshSequenceTest, FormatFromPath) {
  EXPECT_EQ(SequenceFormatFromPath("a/b.pc2"), SequenceFormat::kPc2);
  EXPECT_EQ(SequenceFormatFromPath("a/b.PC2"), SequenceFormat::kPc2);
  EXPECT_EQ(SequenceFormatFromPath("b.mdd"), SequenceFormat::kMdd);
  EXPECT_EQ(SequenceFormatFromPath("b.usda"), SequenceFormat::kUsda);
  EXPECT_EQ(SequenceFormatFromPath("out/frames"), SequenceFormat::kObjFolder);
  EXPECT_EQ(SequenceFormatFromPath("out/frames/"), SequenceFormat::kObjFolder);
  EXPECT_THROW(SequenceFormatFromPath("b.usdc"), InputError);
  EXPECT_THROW(SequenceFormatFromPath("b.abc"), InputError);
  EXPECT_TRUE(SequenceFormatHasTopology(SequenceFormat::kUsda));
  EXPECT_FALSE(SequenceFormatHasTopology(SequenceFormat::kPc2));
}

TEST(MeshSequenceTest, TruncatedOrCorruptBinaryFilesAreRefused) {
  const TempDir temp_dir("hmc_mesh_sequence_" + std::string("corrupt"));
  const fs::path& dir = temp_dir.path();
  const MeshSequence seq = RandomSequence(7, 3, true);
  for (const char* name : {"seq.pc2", "seq.mdd"}) {
    const fs::path file = dir / name;
    for (const int64_t drop : {1, 11, 12, 300}) {
      WriteMeshSequence(file, seq);
      Truncate(file, drop);
      ExpectInputErrorNaming(file, [&] { ReadMeshSequence(file); },
                             "truncated");
    }
    // Trailing bytes are refused too (except a whole extra MDD rest frame,
    // tested below).
    WriteMeshSequence(file, seq);
    { std::ofstream(file, std::ios::app | std::ios::binary) << "xyz"; }
    ExpectInputErrorNaming(file, [&] { ReadMeshSequence(file); }, "trailing");
    // Empty file.
    { std::ofstream(file, std::ios::trunc | std::ios::binary); }
    ExpectInputErrorNaming(file, [&] { ReadMeshSequence(file); });
  }
  // Wrong magic.
  WriteMeshSequence(dir / "seq.pc2", seq);
  std::string bytes = Bytes(dir / "seq.pc2");
  bytes[5] = 'X';
  WriteFileAtomic(dir / "bad.pc2", bytes);
  ExpectInputErrorNaming(dir / "bad.pc2",
                         [&] { ReadMeshSequence(dir / "bad.pc2"); },
                         "POINTCACHE2");
  // A NaN coordinate.
  bytes = Bytes(dir / "seq.pc2");
  const float nan = std::nanf("");
  std::memcpy(bytes.data() + 32 + 12 * 2, &nan, 4);
  WriteFileAtomic(dir / "nan.pc2", bytes);
  ExpectInputErrorNaming(dir / "nan.pc2",
                         [&] { ReadMeshSequence(dir / "nan.pc2"); },
                         "not finite");
  // A topology with another vertex count.
  TriMesh other = seq.topology;
  other.V.conservativeResize(other.V.rows() - 1, 3);
  ExpectInputErrorNaming(dir / "seq.pc2",
                         [&] { ReadMeshSequence(dir / "seq.pc2", &other); },
                         "vertices");
  // Missing file.
  ExpectInputErrorNaming(dir / "none.mdd",
                         [&] { ReadMeshSequence(dir / "none.mdd"); });
}

TEST(MeshSequenceTest, MddWithBlendersRestFrameDropsIt) {
  const TempDir temp_dir("hmc_mesh_sequence_" + std::string("mdd_rest"));
  const fs::path& dir = temp_dir.path();
  MeshSequence seq = RandomSequence(9, 3, true);
  seq.start_frame = 0;  // Blender's exporter writes times 0, 1/fps, ...
  WriteMeshSequence(dir / "seq.mdd", seq);
  const std::string bytes = Bytes(dir / "seq.mdd");
  const size_t header = 8 + 4 * 3;
  const size_t frame_bytes = seq.frames[0].rows() * 12;
  // Blender's layout: header counting 3 frames, 3 times, rest frame, frames.
  const std::string rest(frame_bytes, '\0');
  WriteFileAtomic(dir / "blender.mdd",
                  bytes.substr(0, header) + rest + bytes.substr(header));
  const MeshSequence back = ReadMeshSequence(dir / "blender.mdd");
  ExpectSameFrames(seq, back);
  EXPECT_EQ(back.start_frame, 0);
}

TEST(MeshSequenceTest, MddFrameNumbersNeedTheRightRate) {
  const TempDir temp_dir("hmc_mesh_sequence_" + std::string("mdd_rate"));
  const fs::path& dir = temp_dir.path();
  MeshSequence seq = RandomSequence(4, 1, true);
  seq.fps = 24.0;
  seq.start_frame = 1;
  WriteMeshSequence(dir / "one.mdd", seq);
  // One frame carries no rate: at the default 30 fps, 1/24 s is no frame.
  ExpectInputErrorNaming(dir / "one.mdd",
                         [&] { ReadMeshSequence(dir / "one.mdd"); },
                         "consecutive whole frames");
  MeshSequenceReadOptions options;
  options.fps = 24.0;
  EXPECT_EQ(ReadMeshSequence(dir / "one.mdd", options).start_frame, 1);
}

TEST(MeshSequenceTest, MddFrameRateAndStartSurviveLateFrameNumbers) {
  // float32 times lose precision at high frame numbers (VFX shots start at
  // 1001; long takes run far beyond): the rate and start must still come
  // back exactly from as few as two frames. (Late frames within about 25 of
  // a multiple of 1000 are ambiguous at NTSC rates: next test.)
  const TempDir temp_dir("hmc_mesh_sequence_" + std::string("mdd_late"));
  const fs::path& dir = temp_dir.path();
  for (const int start : {1001, 86399, 199555}) {
    for (const int num_frames : {2, 4, 50}) {
      for (const double fps :
           {24.0, 25.0, 60.0, 24000.0 / 1001.0, 30000.0 / 1001.0}) {
        MeshSequence seq = RandomSequence(start + num_frames, num_frames, true);
        seq.start_frame = start;
        seq.fps = fps;
        WriteMeshSequence(dir / "seq.mdd", seq);
        const MeshSequence back = ReadMeshSequence(dir / "seq.mdd");
        EXPECT_EQ(back.start_frame, start) << fps << " fps, " << num_frames;
        EXPECT_EQ(back.fps, fps) << start << ", " << num_frames;
      }
    }
  }
}

TEST(MeshSequenceTest, MddCannotTellNtscFromWholeRatesAtSomeFrames) {
  // Frame 1000 k at N x 1000/1001 fps is at the same time as frame 1001 k at
  // N fps: such files are identical, and the reader takes the whole rate.
  const TempDir temp_dir("hmc_mesh_sequence_" + std::string("mdd_ntsc"));
  const fs::path& dir = temp_dir.path();
  MeshSequence ntsc = RandomSequence(12, 3, true);
  ntsc.start_frame = 200000;
  ntsc.fps = 30000.0 / 1001.0;
  MeshSequence whole = ntsc;
  whole.start_frame = 200200;
  whole.fps = 30.0;
  WriteMeshSequence(dir / "ntsc.mdd", ntsc);
  WriteMeshSequence(dir / "whole.mdd", whole);
  EXPECT_EQ(Bytes(dir / "ntsc.mdd"), Bytes(dir / "whole.mdd"));
  const MeshSequence back = ReadMeshSequence(dir / "ntsc.mdd");
  EXPECT_EQ(back.fps, 30.0);
  EXPECT_EQ(back.start_frame, 200200);
  MeshSequenceReadOptions options;
  options.fps = ntsc.fps;
  EXPECT_EQ(ReadMeshSequence(dir / "ntsc.mdd", options).start_frame, 200000);
}

TEST(MeshSequenceTest, CorruptUsdaIsRefusedWithFileAndLine) {
  const TempDir temp_dir("hmc_mesh_sequence_" + std::string("usda_corrupt"));
  const fs::path& dir = temp_dir.path();
  const MeshSequence seq = RandomSequence(3, 3, true);
  WriteMeshSequence(dir / "seq.usda", seq);
  const std::string text = Bytes(dir / "seq.usda");
  // Cut inside the time samples.
  const size_t cut = text.find("point3f[] points.timeSamples") + 100;
  WriteFileAtomic(dir / "cut.usda", text.substr(0, cut));
  try {
    ReadMeshSequence(dir / "cut.usda");
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), dir / "cut.usda");
    EXPECT_GT(e.line(), 1);
  }
  // A vertex index out of range.
  std::string bad = text;
  const size_t at = bad.find("faceVertexIndices = [") + 21;
  bad.insert(at, "9999");
  bad.erase(at + 4, bad.find(',', at + 4) - at - 4);
  WriteFileAtomic(dir / "index.usda", bad);
  ExpectInputErrorNaming(dir / "index.usda",
                         [&] { ReadMeshSequence(dir / "index.usda"); },
                         "9999");
  WriteFileAtomic(dir / "not.usda", "hello");
  ExpectInputErrorNaming(dir / "not.usda",
                         [&] { ReadMeshSequence(dir / "not.usda"); }, "usda");
}

TEST(MeshSequenceTest, ObjFolderWithAGapOrForeignFilesIsRefused) {
  const TempDir temp_dir("hmc_mesh_sequence_" + std::string("obj_bad"));
  const fs::path& dir = temp_dir.path();
  const MeshSequence seq = RandomSequence(2, 3, true);
  WriteMeshSequence(dir / "frames", seq);
  fs::remove(dir / "frames" / fmt::format("frame_{:06d}.obj",
                                          seq.start_frame + 1));
  ExpectInputErrorNaming(dir / "frames",
                         [&] { ReadMeshSequence(dir / "frames"); }, "missing");
  // A folder holding anything but frames is not replaced (it would be
  // deleted).
  fs::create_directories(dir / "mine");
  WriteFileAtomic(dir / "mine" / "notes.txt", "keep me");
  ExpectInputErrorNaming(dir / "mine",
                         [&] { WriteMeshSequence(dir / "mine", seq); },
                         "notes.txt");
  EXPECT_EQ(ReadFile(dir / "mine" / "notes.txt"), "keep me");
  EXPECT_EQ(CountEntries(dir / "mine"), 1);
}

TEST(MeshSequenceTest, FailedWriteKeepsThePreviousOutput) {
  const TempDir temp_dir("hmc_mesh_sequence_" + std::string("atomic"));
  const fs::path& dir = temp_dir.path();
  const MeshSequence good = RandomSequence(6, 3, true);
  MeshSequence bad = RandomSequence(8, 3, true);
  bad.frames[2](1, 1) = std::nan("");  // the last frame is broken
  for (const char* name : {"seq.pc2", "seq.mdd", "seq.usda", "frames"}) {
    WriteMeshSequence(dir / name, good);
    const MeshSequence before = ReadMeshSequence(dir / name);
    const int entries = CountEntries(dir);
    ExpectInputErrorNaming(dir / name,
                           [&] { WriteMeshSequence(dir / name, bad); },
                           "not a finite");
    ExpectSameFrames(before, ReadMeshSequence(dir / name));
    EXPECT_EQ(CountEntries(dir), entries) << "temporary left by " << name;
  }
  // Other refused sequences: vertex counts differ, no topology for formats
  // that need one, no frames.
  MeshSequence ragged = good;
  ragged.frames[1].conservativeResize(ragged.frames[1].rows() - 1, 3);
  EXPECT_THROW(WriteMeshSequence(dir / "seq.pc2", ragged), InputError);
  MeshSequence points_only = good;
  points_only.topology = TriMesh();
  EXPECT_THROW(WriteMeshSequence(dir / "seq.usda", points_only), InputError);
  EXPECT_THROW(WriteMeshSequence(dir / "frames", points_only), InputError);
  WriteMeshSequence(dir / "points_only.pc2", points_only);  // fine
  MeshSequence empty = good;
  empty.frames.clear();
  EXPECT_THROW(WriteMeshSequence(dir / "empty.mdd", empty), InputError);
  EXPECT_FALSE(fs::exists(dir / "empty.mdd"));
}

// The point caches written frame by frame (the solve's streaming output)
// are the bytes WriteMeshSequence writes for the same frames, for values
// that are not float32 (rounded alike) on varied seeds; a frame it would
// refuse, too few or too many frames, or a producer that throws leave the
// previous file and no temporary.
TEST(MeshSequenceTest, StreamedPointCachesEqualWholeWrites) {
  const TempDir temp_dir("hmc_mesh_sequence_" + std::string("streamed"));
  const fs::path& dir = temp_dir.path();
  for (unsigned seed : {3u, 11u, 29u}) {
    const MeshSequence seq = RandomSequence(seed, 2 + static_cast<int>(seed % 5), false);
    for (const char* ext : {".pc2", ".mdd"}) {
      const fs::path whole = dir / (std::string("whole") + ext);
      const fs::path streamed = dir / (std::string("streamed") + ext);
      WriteMeshSequence(whole, seq);
      WriteMeshSequenceStreamed(streamed, static_cast<int64_t>(seq.frames.size()),
                                static_cast<int>(seq.frames[0].rows()), seq.start_frame, seq.fps,
                                [&](const EmitMesh& emit) {
                                  for (const MatX3d& X : seq.frames) emit(X);
                                });
      EXPECT_EQ(ReadFile(whole), ReadFile(streamed)) << ext << " seed " << seed;
    }
  }
  const MeshSequence good = RandomSequence(6, 3, true);
  const int V = static_cast<int>(good.frames[0].rows());
  for (const char* name : {"seq.pc2", "seq.mdd"}) {
    const fs::path path = dir / name;
    WriteMeshSequence(path, good);
    const std::string before = ReadFile(path);
    const int entries = CountEntries(dir);
    auto write = [&](int64_t announced, int emitted, bool broken) {
      WriteMeshSequenceStreamed(path, announced, V, good.start_frame, good.fps,
                                [&](const EmitMesh& emit) {
                                  for (int f = 0; f < emitted; ++f) {
                                    MatX3d X = good.frames[f % 3];
                                    if (broken && f == emitted - 1) X(0, 2) = INFINITY;
                                    emit(X);
                                  }
                                });
    };
    ExpectInputErrorNaming(path, [&] { write(3, 3, true); }, "not a finite");
    ExpectInputErrorNaming(path, [&] { write(3, 2, false); }, "2 of the 3 frames");
    ExpectInputErrorNaming(path, [&] { write(3, 4, false); }, "more than the 3 frames");
    EXPECT_THROW(WriteMeshSequenceStreamed(path, 3, V, good.start_frame, good.fps,
                                           [](const EmitMesh&) { throw std::runtime_error("x"); }),
                 std::runtime_error);
    EXPECT_EQ(ReadFile(path), before) << name;
    EXPECT_EQ(CountEntries(dir), entries) << "temporary left by " << name;
  }
  EXPECT_THROW(WriteMeshSequenceStreamed(dir / "seq.usda", 1, V, 1, 30, [](const EmitMesh&) {}),
               InputError);
}

// Found by fuzzing (docs/reliability.md): headers whose sample x point
// counts overflow int64 when multiplied out (signed overflow, UBSan). They
// are refused as lying headers, naming the file.
TEST(MeshSequenceTest, FuzzedHeadersWithOverflowingCountsAreRefused) {
  const char* root = std::getenv("HMC_SOURCE_DIR");
  const std::filesystem::path dir =
      std::filesystem::path(root ? root : ".") / "tests/fixtures/fuzz_crashes";
  for (const char* name : {"pc2_header_overflow.pc2", "mdd_header_overflow.mdd"}) {
    try {
      ReadMeshSequence(dir / name);
      ADD_FAILURE() << "accepted " << name;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace hmc
