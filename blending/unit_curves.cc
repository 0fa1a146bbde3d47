// Animation curves out (blending/unit_curves.h; docs/method.md, "Animation
// curves"; formats: docs/formats.md, "Unit weights and curves").
#include "blending/unit_curves.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <iterator>
#include <map>
#include <ostream>

#include <fmt/format.h>

#include "core/error.h"
#include "core/file_util.h"
#include "core/parallel.h"
#include "core/usd_text.h"

namespace hmc {
namespace {

// "AU12_lip_corner_puller_L_050" -> ("AU12_lip_corner_puller_L", 0.5); a
// name without the three-digit suffix is a unit at 100 %.
std::pair<std::string, double> UnitOfShapeName(const std::string& name) {
  const size_t n = name.size();
  if (n > 4 && name[n - 4] == '_' && std::isdigit(static_cast<unsigned char>(name[n - 3])) &&
      std::isdigit(static_cast<unsigned char>(name[n - 2])) &&
      std::isdigit(static_cast<unsigned char>(name[n - 1]))) {
    return {name.substr(0, n - 4), std::stoi(name.substr(n - 3)) / 100.0};
  }
  return {name, 1.0};
}

// A USD prim name from a unit name: letters, digits and '_', not starting
// with a digit.
std::string UsdIdentifier(const std::string& name) {
  std::string id;
  for (char c : name) id += std::isalnum(static_cast<unsigned char>(c)) ? c : '_';
  if (id.empty() || std::isdigit(static_cast<unsigned char>(id[0]))) id = "_" + id;
  return id;
}

void AppendFloat(std::string* text, double x) { AppendUsdFloat(text, x); }

void AppendVec3(std::string* text, const Vec3& v) {
  *text += '(';
  AppendFloat(text, v.x());
  *text += ", ";
  AppendFloat(text, v.y());
  *text += ", ";
  AppendFloat(text, v.z());
  *text += ')';
}

const char* kIdentity4 = "( (1, 0, 0, 0), (0, 1, 0, 0), (0, 0, 1, 0), (0, 0, 0, 1) )";

}  // namespace

UnitRig UnitRigFromActor(const Actor& actor) {
  UnitRig rig;
  std::map<std::string, int> index;
  for (size_t n = 0; n < actor.shapes.size(); ++n) {
    const std::string& name = actor.shapes[n].name;
    if (name.find("__") != std::string::npos) continue;  // a combination
    const auto [unit, activation] = UnitOfShapeName(name);
    if (!(activation > 0)) continue;
    const auto it = index.find(unit);
    if (it == index.end()) {
      index[unit] = static_cast<int>(rig.names.size());
      rig.names.push_back(unit);
      rig.shape.push_back(static_cast<int>(n));
      rig.activation.push_back(activation);
    } else if (activation > rig.activation[it->second]) {
      rig.shape[it->second] = static_cast<int>(n);
      rig.activation[it->second] = activation;
    }
  }
  if (rig.names.empty()) {
    throw InputError(fmt::format(
        "actor '{}': no unit to animate (every shape is a combination, named with \"__\")",
        actor.name));
  }
  const MatX3d& x0 = actor.neutral.V;
  for (size_t u = 0; u < rig.names.size(); ++u) {
    const Shape& shape = actor.shapes[rig.shape[u]];
    MatX3d x = x0 + shape.displacement;
    if (actor.jaw_rig) x = Unskin(*actor.jaw_rig, shape.jaw, x);
    rig.displacement.push_back((x - x0) / rig.activation[u]);
  }
  return rig;
}

MatX3d EvaluateUnitRig(const UnitRig& rig, const Actor& actor, const Eigen::VectorXd& w,
                       const JawPose& jaw) {
  MatX3d x = actor.neutral.V;
  for (size_t u = 0; u < rig.names.size(); ++u) {
    if (w[u] != 0.0) x += w[u] * rig.displacement[u];
  }
  return actor.jaw_rig ? Skin(*actor.jaw_rig, jaw, x) : x;
}

UnitFitter::UnitFitter(const UnitRig& rig, const Actor& actor) : rig_(rig), actor_(actor) {
  const int U = static_cast<int>(rig.names.size());
  G_.resize(U, U);
  ParallelFor(0, U, [&](int64_t i) {
    for (int j = 0; j < U; ++j) {
      G_(i, j) = (rig.displacement[i].array() * rig.displacement[j].array()).sum();
    }
  });
}

double UnitFitter::Fit(const MatX3d& mesh, const JawPose& pose, Eigen::VectorXd* weights) const {
  const int U = static_cast<int>(rig_.names.size());
  const MatX3d y =
      (actor_.jaw_rig ? Unskin(*actor_.jaw_rig, pose, mesh) : mesh) - actor_.neutral.V;
  Eigen::VectorXd c(U);
  for (int u = 0; u < U; ++u) c[u] = (rig_.displacement[u].array() * y.array()).sum();
  // Projected coordinate descent on 1/2 w'Gw - c'w, 0 <= w <= 1: each
  // step minimises exactly along one coordinate within the box, so the
  // cost never rises; stopped when no weight moves by more than 1e-10.
  Eigen::VectorXd& w = *weights;
  w = Eigen::VectorXd::Zero(U);
  for (int sweep = 0; sweep < 20000; ++sweep) {
    double largest = 0.0;
    for (int u = 0; u < U; ++u) {
      if (!(G_(u, u) > 0)) continue;  // a unit that moves nothing
      const double step = (c[u] - G_.row(u).dot(w)) / G_(u, u);
      const double next = std::clamp(w[u] + step, 0.0, 1.0);
      largest = std::max(largest, std::abs(next - w[u]));
      w[u] = next;
    }
    if (largest < 1e-10) break;
  }
  return (EvaluateUnitRig(rig_, actor_, w, pose) - mesh).rowwise().norm().mean();
}

void UnitFit::Summarize() {
  const int F = static_cast<int>(mean_mm.size());
  mean_mm_all = 0.0;
  max_frame_mean_mm = 0.0;
  for (double e : mean_mm) {
    mean_mm_all += e / std::max(F, 1);
    max_frame_mean_mm = std::max(max_frame_mean_mm, e);
  }
}

UnitFit FitUnitWeights(const UnitRig& rig, const Actor& actor, const std::vector<MatX3d>& meshes,
                       const std::vector<JawPose>& jaw) {
  const UnitFitter fitter(rig, actor);
  const int F = static_cast<int>(meshes.size());
  UnitFit fit;
  fit.weights.assign(F, Eigen::VectorXd());
  fit.mean_mm.assign(F, 0.0);
  ParallelFor(0, F, [&](int64_t f) {
    fit.mean_mm[f] = fitter.Fit(meshes[f], jaw.empty() ? JawPose() : jaw[f], &fit.weights[f]);
  });
  fit.Summarize();
  return fit;
}

UnitAnimation MakeUnitAnimation(const UnitRig& rig, const Actor& actor, const UnitFit& fit,
                                const std::vector<JawPose>& jaw, int start_frame, double fps) {
  UnitAnimation a;
  a.channels = rig.names;
  if (actor.jaw_rig) {
    a.channels.insert(a.channels.end(), {"jaw_open_deg", "jaw_lateral_deg", "jaw_protrude_mm"});
  }
  a.start_frame = start_frame;
  a.fps = fps;
  for (size_t f = 0; f < fit.weights.size(); ++f) {
    std::vector<double> row(fit.weights[f].data(), fit.weights[f].data() + fit.weights[f].size());
    if (actor.jaw_rig) {
      const JawPose pose = jaw.empty() ? JawPose() : jaw[f];
      row.insert(row.end(), {pose.open_deg, pose.lateral_deg, pose.protrude_mm});
    }
    a.values.push_back(std::move(row));
  }
  return a;
}

void WriteUnitWeightsCsv(const std::filesystem::path& path, const UnitAnimation& animation) {
  std::string text = "frame";
  for (const std::string& c : animation.channels) text += "," + c;
  text += "\n";
  for (size_t f = 0; f < animation.values.size(); ++f) {
    fmt::format_to(std::back_inserter(text), "{}", animation.start_frame + static_cast<int>(f));
    for (double v : animation.values[f]) fmt::format_to(std::back_inserter(text), ",{:.9g}", v);
    text += "\n";
  }
  WriteFileAtomic(path, text);
}

void WriteUnitCurvesCsv(const std::filesystem::path& path, const UnitAnimation& animation) {
  std::string text = "channel,frame,time_s,value\n";
  for (size_t c = 0; c < animation.channels.size(); ++c) {
    for (size_t f = 0; f < animation.values.size(); ++f) {
      const int frame = animation.start_frame + static_cast<int>(f);
      fmt::format_to(std::back_inserter(text), "{},{},{:.9g},{:.9g}\n", animation.channels[c],
                     frame, frame / animation.fps, animation.values[f][c]);
    }
  }
  WriteFileAtomic(path, text);
}

void WriteUnitRigUsda(const std::filesystem::path& path, const UnitRig& rig, const Actor& actor,
                      const UnitAnimation& animation, const std::vector<JawPose>& jaw) {
  const TriMesh& mesh = actor.neutral;
  const int U = static_cast<int>(rig.names.size());
  const int first = animation.start_frame;
  const int last = first + static_cast<int>(animation.values.size()) - 1;
  const bool has_jaw = actor.jaw_rig.has_value();
  std::string text;
  AppendUsdStageHeader(&text, "rig",
                       "hmc unit animation: the actor's units as blend shapes, their weights "
                       "time-sampled (mm, head space, +y up; docs/formats.md)",
                       first, last, animation.fps);
  text += "def SkelRoot \"rig\"\n{\n";
  // Tokens: the unit names as written in weights.csv.
  std::string shape_tokens = "[";
  for (int u = 0; u < U; ++u) shape_tokens += fmt::format("{}\"{}\"", u ? ", " : "", rig.names[u]);
  shape_tokens += "]";
  const std::string joints = has_jaw ? "[\"root\", \"root/jaw\"]" : "[\"root\"]";
  const std::string identities =
      has_jaw ? fmt::format("[{}, {}]", kIdentity4, kIdentity4) : fmt::format("[{}]", kIdentity4);
  fmt::format_to(std::back_inserter(text),
                 "    def Skeleton \"skeleton\" (\n"
                 "        prepend apiSchemas = [\"SkelBindingAPI\"]\n"
                 "    )\n    {{\n"
                 "        uniform token[] joints = {}\n"
                 "        uniform matrix4d[] bindTransforms = {}\n"
                 "        uniform matrix4d[] restTransforms = {}\n"
                 "        rel skel:animationSource = </rig/skeleton/animation>\n\n"
                 "        def SkelAnimation \"animation\"\n        {{\n"
                 "            uniform token[] joints = {}\n"
                 "            uniform token[] blendShapes = {}\n"
                 "            float[] blendShapeWeights.timeSamples = {{\n",
                 joints, identities, identities, joints, shape_tokens);
  for (size_t f = 0; f < animation.values.size(); ++f) {
    fmt::format_to(std::back_inserter(text), "                {}: [", first + static_cast<int>(f));
    for (int u = 0; u < U; ++u) {
      text += u ? ", " : "";
      AppendFloat(&text, animation.values[f][u]);
    }
    text += "],\n";
  }
  text += "            }\n";
  // The jaw joint's transform per frame: T(theta), the solve's skinning
  // (linear blend with the root's identity by the vertex's jaw weight).
  text += "            float3[] translations.timeSamples = {\n";
  std::string rotations = "            quatf[] rotations.timeSamples = {\n";
  for (size_t f = 0; f < animation.values.size(); ++f) {
    const int frame = first + static_cast<int>(f);
    fmt::format_to(std::back_inserter(text), "                {}: [(0, 0, 0)", frame);
    fmt::format_to(std::back_inserter(rotations), "                {}: [(1, 0, 0, 0)", frame);
    if (has_jaw) {
      const Rigid3 t = actor.jaw_rig->Transform(jaw.empty() ? JawPose() : jaw[f]);
      text += ", ";
      AppendVec3(&text, t.translation());
      const Eigen::Quaterniond q(t.linear());
      rotations += ", (";
      AppendFloat(&rotations, q.w());
      for (double v : {q.x(), q.y(), q.z()}) {
        rotations += ", ";
        AppendFloat(&rotations, v);
      }
      rotations += ')';
    }
    text += "],\n";
    rotations += "],\n";
  }
  text += "            }\n" + rotations + "            }\n";
  text += has_jaw ? "            half3[] scales = [(1, 1, 1), (1, 1, 1)]\n"
                  : "            half3[] scales = [(1, 1, 1)]\n";
  text += "        }\n    }\n\n";

  // The mesh: the neutral, bound to the skeleton, with the blend shapes.
  text +=
      "    def Mesh \"face\" (\n"
      "        prepend apiSchemas = [\"SkelBindingAPI\"]\n"
      "    )\n    {\n";
  AppendUsdFaces(&text, mesh, "        ");
  text += "        point3f[] points = [";
  for (int v = 0; v < mesh.NumVertices(); ++v) {
    text += v ? ", " : "";
    AppendVec3(&text, mesh.V.row(v).transpose());
  }
  text += "]\n";
  AppendUsdUvs(&text, mesh, "        ");
  text += "        uniform token subdivisionScheme = \"none\"\n";
  text += "        rel skel:skeleton = </rig/skeleton>\n";
  fmt::format_to(std::back_inserter(text), "        matrix4d primvars:skel:geomBindTransform = {}\n",
                 kIdentity4);
  const int per_vertex = has_jaw ? 2 : 1;
  std::string indices = "        int[] primvars:skel:jointIndices = [";
  std::string weights = "        float[] primvars:skel:jointWeights = [";
  for (int v = 0; v < mesh.NumVertices(); ++v) {
    const char* sep = v ? ", " : "";
    if (has_jaw) {
      const double w = actor.jaw_rig->weights[v];
      indices += fmt::format("{}0, 1", sep);
      weights += fmt::format("{}{}, {}", sep, static_cast<float>(1.0 - w), static_cast<float>(w));
    } else {
      indices += fmt::format("{}0", sep);
      weights += fmt::format("{}1", sep);
    }
  }
  for (std::string* s : {&indices, &weights}) {
    *s += fmt::format("] (\n            elementSize = {}\n            interpolation = \"vertex\"\n"
                      "        )\n",
                      per_vertex);
    text += *s;
  }
  fmt::format_to(std::back_inserter(text), "        uniform token[] skel:blendShapes = {}\n",
                 shape_tokens);
  text += "        rel skel:blendShapeTargets = [";
  for (int u = 0; u < U; ++u) {
    fmt::format_to(std::back_inserter(text), "{}</rig/face/{}>", u ? ", " : "",
                   UsdIdentifier(rig.names[u]));
  }
  text += "]\n";
  for (int u = 0; u < U; ++u) {
    const MatX3d& d = rig.displacement[u];
    std::string offsets, points;
    for (int v = 0; v < d.rows(); ++v) {
      if (d.row(v).squaredNorm() == 0.0) continue;
      offsets += offsets.empty() ? "" : ", ";
      AppendVec3(&offsets, d.row(v).transpose());
      points += fmt::format("{}{}", points.empty() ? "" : ", ", v);
    }
    fmt::format_to(std::back_inserter(text),
                   "\n        def BlendShape \"{}\"\n        {{\n"
                   "            uniform vector3f[] offsets = [{}]\n"
                   "            uniform int[] pointIndices = [{}]\n        }}\n",
                   UsdIdentifier(rig.names[u]), offsets, points);
  }
  text += "    }\n}\n";
  WriteFileAtomic(path, text);
}

}  // namespace hmc
