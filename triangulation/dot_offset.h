// The painted dot's offset (docs/calibration.md, "The painted dot's
// offset"). A dot of radius r painted on curved skin is a cap; its rim lies
// below the marker's tangent plane, and a tracker that centres the dot's
// image finds about the projection of the rim's centre, not of the marker
// (docs/footage.md, "Ground truth of the dots"). Triangulating the centroids
// in two views therefore gives the rim's centre.
//
// With the skin near the marker as the quadric z = a x^2 + b xy + c y^2 in
// the marker's tangent frame (z along the outward normal n), the rim (a
// circle of radius r about the marker, to first order) has its centre at
//
//   o = (a + c) r^2 / 2 * n      (= -r^2 / (2 R) n on a sphere of radius R),
//
// so the marker is the triangulated point minus o. The quadric is fitted
// (least squares, with linear and constant terms) to the actor's neutral
// vertices within fit_radius of the marker whose normals agree with n; the
// neutral stands in for the current expression and helmet space for head
// space (their difference, the head's slip of a degree or two, turns o by
// as much).
#pragma once

#include <map>
#include <string>

#include "core/actor.h"
#include "core/types.h"

namespace hmc {

// Per marker name, o in head space (mm). Markers whose neighbourhood has too
// few vertices for the fit get no entry.
std::map<std::string, Vec3> DotRimOffsets(const Actor& actor, double dot_radius,
                                          double fit_radius);

}  // namespace hmc
