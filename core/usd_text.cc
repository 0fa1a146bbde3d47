#include "core/usd_text.h"

#include <iterator>

#include <fmt/format.h>

namespace hmc {

void AppendUsdFloat(std::string* text, double x, int precision) {
  const float value = static_cast<float>(x);
  if (precision >= 9) {
    fmt::format_to(std::back_inserter(*text), "{}", value);
  } else {
    fmt::format_to(std::back_inserter(*text), "{:.{}g}", value, precision);
  }
}

void AppendUsdStageHeader(std::string* text, const std::string& default_prim,
                          const std::string& doc, int first, int last, double fps,
                          const std::string& timecode) {
  *text += "#usda 1.0\n(\n";
  if (!timecode.empty()) {
    // USD has no field of its own for the footage's timecode: custom layer data.
    fmt::format_to(std::back_inserter(*text),
                   "    customLayerData = {{\n"
                   "        string timecode = \"{}\"\n"
                   "    }}\n",
                   timecode);
  }
  fmt::format_to(std::back_inserter(*text),
                 "    defaultPrim = \"{}\"\n"
                 "    doc = \"{}\"\n"
                 "    endTimeCode = {}\n"
                 "    framesPerSecond = {}\n"
                 "    metersPerUnit = 0.001\n"
                 "    startTimeCode = {}\n"
                 "    timeCodesPerSecond = {}\n"
                 "    upAxis = \"Y\"\n"
                 ")\n\n",
                 default_prim, doc, last, fps, first, fps);
}

void AppendUsdFaces(std::string* text, const TriMesh& mesh, const std::string& indent) {
  *text += indent + "int[] faceVertexCounts = [";
  for (int t = 0; t < mesh.NumFaces(); ++t) *text += t ? ", 3" : "3";
  *text += "]\n" + indent + "int[] faceVertexIndices = [";
  for (int t = 0; t < mesh.NumFaces(); ++t) {
    fmt::format_to(std::back_inserter(*text), "{}{}, {}, {}", t ? ", " : "", mesh.F(t, 0),
                   mesh.F(t, 1), mesh.F(t, 2));
  }
  *text += "]\n" + indent + "uniform token orientation = \"rightHanded\"\n";
}

void AppendUsdUvs(std::string* text, const TriMesh& mesh, const std::string& indent,
                  int precision) {
  if (!mesh.HasUVs()) return;
  *text += indent + "texCoord2f[] primvars:st = [";
  for (int i = 0; i < mesh.UV.rows(); ++i) {
    *text += i ? ", (" : "(";
    AppendUsdFloat(text, mesh.UV(i, 0), precision);
    *text += ", ";
    AppendUsdFloat(text, mesh.UV(i, 1), precision);
    *text += ')';
  }
  *text += "] (\n" + indent + "    interpolation = \"faceVarying\"\n" + indent + ")\n";
  *text += indent + "int[] primvars:st:indices = [";
  for (int t = 0; t < mesh.NumFaces(); ++t) {
    fmt::format_to(std::back_inserter(*text), "{}{}, {}, {}", t ? ", " : "", mesh.FUV(t, 0),
                   mesh.FUV(t, 1), mesh.FUV(t, 2));
  }
  *text += "]\n";
}

}  // namespace hmc
