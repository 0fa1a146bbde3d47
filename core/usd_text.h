// Pieces of USD ASCII that more than one writer emits: a triangle mesh's
// faces and UVs (core/mesh_sequence_usda.cc's mesh sequences,
// blending/unit_curves.h's blend-shape rig; docs/formats.md).
#pragma once

#include <string>

#include "core/mesh.h"

namespace hmc {

// USD's float-valued types hold float32: x rounded to float32, written as
// the shortest text that reads back as that float (at most 9 digits), or
// with fewer digits if `precision` (< 9) asks for less.
void AppendUsdFloat(std::string* text, double x, int precision = 9);

// The stage's header: "#usda 1.0" and its metadata (defaultPrim, doc,
// time codes first..last at fps, metersPerUnit 0.001: mm, upAxis Y; the
// footage's SMPTE timecode at `first` as customLayerData when given), then
// a blank line.
void AppendUsdStageHeader(std::string* text, const std::string& default_prim,
                          const std::string& doc, int first, int last, double fps,
                          const std::string& timecode = "");

// `int[] faceVertexCounts`, `int[] faceVertexIndices` and
// `uniform token orientation = "rightHanded"`, each line starting with
// `indent`.
void AppendUsdFaces(std::string* text, const TriMesh& mesh, const std::string& indent);

// `texCoord2f[] primvars:st` (faceVarying) and `int[] primvars:st:indices`;
// nothing for a mesh without UVs.
void AppendUsdUvs(std::string* text, const TriMesh& mesh, const std::string& indent,
                  int precision = 9);

}  // namespace hmc
