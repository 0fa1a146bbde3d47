// Constraints after the solve: markers seen by one camera (docs/method.md,
// "Constraints after the solve"; the paper's "Post-processing" paragraph).
//
// A marker that only one camera saw in a frame is not a bundle (the solve
// fills it from its neighbours) but a ray o + t d on which its surface point
// must lie (triangulate's rays.csv, docs/formats.md). After the blend, each
// frame's solved mesh X is deformed by a smooth displacement field spread
// with the sewing's own natural-neighbour weights,
//
//   X'(v) = X(v) + sum_{j in R} lambda_j(v) delta_j,
//
// R the frame's constrained markers. delta is chosen so that each marker's
// surface point p_i = x(s_i) moves by m_i onto its ray: the |R| x |R|
// system sum_j A_ij delta_j = m_i (three right-hand sides) with A_ij =
// lambda_j at s_i (barycentric over s_i's triangle; about the identity).
// The ray gives no depth. m_i is the move across the ray to q_i, the ray's
// point nearest to p_i: with rays.depth "solve" (the default) the depth
// stays the solve's. With "dataset" m_i also moves along the ray by what
// the dataset's motion at the marker predicts from the move across it
// (measured: better on one actor seed, worse on another; docs/method.md):
// with S = sum_n c_n c_n^T over the shapes' displacements c_n at the site,
// the conditional mean of the along-ray component given the across
// components under N(0, S), with a ridge of 0.3 tr(S) / 3 on the across
// block (the solve's error is not all the dataset's motion). The field is
// the robust solve's own interpolation of what is
// left at the bundles (blending/robust_solver.h, step 5), so it is confined
// to the natural-neighbour region of the constrained markers, is zero at
// the other markers' sites that sit on vertices, and leaves the dataset's
// detail of the blend in place.
//
// A ray whose marker is also a bundle of the frame, or whose surface point
// is behind the ray's origin, or farther from the ray than max_mm (a
// mislabelled dot), is not applied; its status says why.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "blending/natural_neighbour.h"
#include "core/mesh.h"
#include "core/options.h"
#include "core/types.h"

namespace hmc {

struct RayConstraintOptions {
  double max_mm = 5.0;  // a ray farther than this from the solved surface
                        // point is not applied (a mislabelled dot)
  // How the move along the ray is chosen: "solve" leaves the depth the
  // solve's (the move is perpendicular to the ray); "dataset" adds the
  // depth the dataset's motion at the marker predicts from the
  // perpendicular move (the conditional mean under the zero-mean Gaussian
  // whose covariance is sum_n c_n c_n^T over the shapes' displacements c_n
  // at the marker's site).
  std::string depth = "solve";
  double tolerance_mm = 0.0;  // the ray's own error: a surface point is
                              // moved to within this of its ray, not onto
                              // it (soft threshold; 0: onto the ray)

  void Register(OptionFields* fields);
  bool Check() const;
};

// One ray in head space, for the frame at `frame_index` of the sequence.
struct RayConstraint {
  int frame_index = 0;
  int marker = -1;       // index into the actor's markers
  std::string camera;    // for the diagnostics
  Vec3 origin = Vec3::Zero();     // mm, head space
  Vec3 direction = Vec3::Zero();  // unit
};

enum class RayStatus {
  kApplied,
  kObserved,   // the marker is a bundle of the frame: the bundle is kept
  kBadFrame,   // the frame was not solved (it repeats another's mesh)
  kBehind,     // the surface point is behind the camera
  kTooFar,     // farther than max_mm from the ray
};
const char* RayStatusName(RayStatus status);

// Each constraint's distance from its ray before and after (mm).
struct RayResidual {
  RayStatus status = RayStatus::kApplied;
  double before_mm = 0.0;
  double after_mm = 0.0;
};

struct RayConstraintSummary {
  int rays = 0;
  int applied = 0;
  int observed = 0;
  int bad_frame = 0;
  int behind = 0;
  int too_far = 0;
  double mean_before_mm = 0.0;  // over the applied rays
  double max_before_mm = 0.0;
  double mean_after_mm = 0.0;
  double max_after_mm = 0.0;
  std::string BriefReport() const;
};

// Applies every constraint to its frame's mesh in `meshes` (V x 3 each, the
// solve's output). sites: the markers' surface points on the mesh's
// triangles F; nn: the sewing's weights over those sites; observed[f][k]
// whether marker k was a bundle of frame f, frame_ok[f] whether frame f was
// solved (both may be empty: all false / all true). Returns one residual per
// constraint, in the order given. Throws InputError on a marker index out
// of range.
// site_motion: with depth "dataset", per site the 3 x 3 covariance of the
// dataset's motion there (SiteMotionCovariances), else ignored (may be
// empty).
std::vector<RayResidual> ApplyRayConstraints(
    const std::vector<RayConstraint>& rays, const std::vector<SurfacePoint>& sites,
    const MatX3i& F, const NaturalNeighbourWeights& nn,
    const std::vector<std::vector<char>>& observed, const std::vector<char>& frame_ok,
    const RayConstraintOptions& options, std::vector<MatX3d>* meshes,
    const std::vector<Mat3>& site_motion = {});

// The same over meshes found by frame index, for a solve that hands its
// meshes over a few frames at a time: mesh_of(f) is frame f's mesh, or
// nullptr for a frame whose constraints are left to another call (their
// residuals come back default-constructed); frame indices must lie in
// 0..num_frames-1.
std::vector<RayResidual> ApplyRayConstraints(
    const std::vector<RayConstraint>& rays, const std::vector<SurfacePoint>& sites,
    const MatX3i& F, const NaturalNeighbourWeights& nn,
    const std::vector<std::vector<char>>& observed, const std::vector<char>& frame_ok,
    const RayConstraintOptions& options, int num_frames,
    const std::function<MatX3d*(int f)>& mesh_of, const std::vector<Mat3>& site_motion = {});

// sum_n c_{k,n} c_{k,n}^T per site k, c_{k,n} the displacement of shape n
// (V x 3 each, as the actor holds it: the jaw's motion included) at site
// k.
std::vector<Mat3> SiteMotionCovariances(const std::vector<MatX3d>& displacements,
                                        const std::vector<SurfacePoint>& sites, const MatX3i& F);

RayConstraintSummary SummarizeRays(const std::vector<RayResidual>& residuals);

}  // namespace hmc
