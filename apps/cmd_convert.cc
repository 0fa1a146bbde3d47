// `hmc convert IN OUT`: converts a mesh sequence between .pc2, .mdd, .usda
// and OBJ-frame folders, chosen by extension (docs/formats.md, "Mesh
// sequences"). What the input lacks (triangles and UVs for .pc2/.mdd, the
// frame rate for .pc2 and OBJ folders) comes from --topology and --fps.
#include <memory>
#include <optional>
#include <string>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "apps/command.h"
#include "core/error.h"
#include "core/mesh_sequence.h"
#include "core/obj_io.h"
#include "tracking/video_timecode.h"

namespace hmc {
namespace {

struct ConvertArgs {
  std::string in;
  std::string out;
  std::string topology;  // OBJ with the sequence's vertex order
  double fps = 0.0;      // 0: the input's, else 30
  int start_frame = 1;
  bool start_frame_given = false;
  int precision = 9;     // significant digits of OBJ frames
  std::string timecode;  // the footage's frame 1 (SMPTE); "" keeps the input's
};

const char* FormatName(SequenceFormat format) {
  switch (format) {
    case SequenceFormat::kPc2:
      return "PC2";
    case SequenceFormat::kMdd:
      return "MDD";
    case SequenceFormat::kUsda:
      return "USDA";
    case SequenceFormat::kObjFolder:
      return "OBJ folder";
  }
  return "?";
}

int RunConvert(const ConvertArgs& args) {
  const SequenceFormat in_format = SequenceFormatFromPath(args.in);
  const SequenceFormat out_format = SequenceFormatFromPath(args.out);
  PrepareOutputPaths({{args.out, "OUT", out_format == SequenceFormat::kObjFolder}},
                     {{args.in, "IN"}, {args.topology, "--topology"}});

  MeshSequenceReadOptions options;
  options.fps = args.fps;
  if (args.start_frame_given) options.start_frame = args.start_frame;
  std::optional<TriMesh> topology;
  if (!args.topology.empty()) {
    topology = ReadObj(args.topology);
    options.topology = &*topology;
  }
  MeshSequence seq = ReadMeshSequence(args.in, options);

  if (topology && SequenceFormatHasTopology(in_format)) {
    // The input has its own triangles; the given ones replace them (e.g.
    // to add UVs), if they fit the vertices.
    if (topology->NumVertices() != seq.frames[0].rows()) {
      ThrowInputError(args.topology, 0,
                      "has {} vertices, the frames of {} have {}",
                      topology->NumVertices(), args.in, seq.frames[0].rows());
    }
    spdlog::info("convert: triangles and UVs from {} replace those of {}",
                 args.topology, args.in);
    seq.topology = *topology;
  }
  if (SequenceFormatHasTopology(out_format) && seq.topology.NumFaces() == 0) {
    throw InputError(fmt::format(
        "{} ({}) needs triangles, but {} ({}) holds only points: give "
        "--topology FILE.obj (the neutral, or any mesh with the same vertex "
        "order)",
        args.out, FormatName(out_format), args.in, FormatName(in_format)));
  }
  const bool in_has_fps = in_format == SequenceFormat::kUsda ||
                          in_format == SequenceFormat::kMdd;
  const bool out_has_fps = out_format == SequenceFormat::kUsda ||
                           out_format == SequenceFormat::kMdd;
  if (args.fps == 0 && !in_has_fps && out_has_fps) {
    spdlog::warn("convert: {} carries no frame rate; writing {} fps (set it "
                 "with --fps)",
                 args.in, seq.fps);
  }

  if (!args.timecode.empty()) {
    seq.timecode = AdvanceTimecode(args.timecode, seq.fps, seq.start_frame - 1, "--timecode");
  }
  if (!seq.timecode.empty() && out_format != SequenceFormat::kUsda) {
    spdlog::info("convert: {} has no place for the timecode {} (only .usda keeps it)", args.out,
                 seq.timecode);
  }
  WriteMeshSequence(args.out, seq, args.precision);
  spdlog::info("convert: {} ({}) -> {} ({}): {} frames {}..{} of {} vertices, "
               "{} triangles, {} fps",
               args.in, FormatName(in_format), args.out,
               FormatName(out_format), seq.frames.size(), seq.start_frame,
               seq.start_frame + static_cast<int>(seq.frames.size()) - 1,
               seq.frames[0].rows(), seq.topology.NumFaces(), seq.fps);
  return 0;
}

}  // namespace

HMC_COMMAND(Convert, "", "convert",
            "Convert a mesh sequence between .pc2, .mdd, .usda and a folder "
            "of OBJ frames (by extension; no extension = OBJ folder)") {
  auto args = std::make_shared<ConvertArgs>();
  app->add_option("IN", args->in,
                  "Input sequence: .pc2, .mdd, .usda, or a folder of "
                  "frame_NNNNNN.obj")
      ->required();
  app->add_option("OUT", args->out,
                  "Output sequence: .pc2, .mdd, .usda, or a folder name "
                  "(written atomically; an existing folder is replaced only "
                  "if it holds nothing but OBJ frames)")
      ->required();
  app->add_option("--topology", args->topology,
                  "OBJ with the triangles and UVs (same vertex order), needed "
                  "from .pc2/.mdd to .usda or an OBJ folder")
      ->check(CLI::ExistingFile);
  app->add_option("--fps", args->fps,
                  "Frames per second; overrides the input's (.pc2 and OBJ "
                  "folders carry none: default 30)")
      ->check(CLI::PositiveNumber);
  CLI::Option* start = app->add_option(
      "--start_frame", args->start_frame,
      "Number of the first frame; overrides the input's");
  app->add_option("--timecode", args->timecode,
                  "SMPTE timecode (HH:MM:SS:FF, ';' for drop-frame) of the footage's frame 1, "
                  "as its video states it: the output (.usda) carries the timecode of its own "
                  "first frame; default: the input's (.usda), else none");
  app->add_option("--precision", args->precision,
                  "Significant digits of OBJ frame coordinates (17: exact "
                  "doubles)")
      ->check(CLI::Range(1, 17))
      ->capture_default_str();
  return [args, start] {
    args->start_frame_given = start->count() > 0;
    return RunConvert(*args);
  };
}

}  // namespace hmc
