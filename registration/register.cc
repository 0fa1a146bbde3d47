#include "registration/register.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>
#include <spdlog/spdlog.h>

#include "core/calibration.h"
#include "core/day_markers.h"
#include "core/error.h"
#include "core/file_util.h"
#include "core/image_io.h"
#include "stabilization/marker_model.h"
#include "stabilization/stabilize.h"
#include "tracking/assignment.h"
#include "triangulation/dot_offset.h"
#include "triangulation/triangulate.h"

namespace hmc {

namespace fs = std::filesystem;

void RegisterOptions::Register(OptionFields* fields) {
  track.Register(fields);
  fields->SetGroup("");
  fields->Add("paint_offset_mm", &paint_offset_mm,
              "largest painted offset the labelling must allow (mm)")
      .Above(0)
      .AtMost(20);
  fields->Add("passes", &passes,
              "track-and-register passes (2: the second names the dots from the first's markers)")
      .AtLeast(1)
      .AtMost(5);
  fields->Add("min_frames", &min_frames,
              "a marker found in fewer than this fraction of the frames is reported not found")
      .Above(0)
      .AtMost(1);
  fields->Add("loose_mm", &loose_mm,
              "a marker whose RMS motion against the surface exceeds this is reported (mm)")
      .Above(0);
  fields->Add("off_surface_mm", &off_surface_mm,
              "a marker whose mean lies further than this from the surface is reported (mm)")
      .Above(0);
}

bool RegisterOptions::Check() const {
  CHECK_OPTION_LIMITS();
  return track.Check();
}

std::string RegisterOutput::BriefReport() const {
  std::vector<double> offsets;
  for (const RegisteredMarker& r : registered) offsets.push_back(r.offset.norm());
  std::sort(offsets.begin(), offsets.end());
  const double median = offsets.empty() ? 0.0 : offsets[offsets.size() / 2];
  return fmt::format(
      "{} markers registered from {} frames in {} passes (median offset {:.2f} mm, pose "
      "correction {:.3f} mm); not found: {}; loose: {}; off the surface: {}",
      registered.size(), frames, passes, median, pose_correction_mm,
      not_found.empty() ? "none" : fmt::format("{}", fmt::join(not_found, " ")),
      loose.empty() ? "none" : fmt::format("{}", fmt::join(loose, " ")),
      off_surface.empty() ? "none" : fmt::format("{}", fmt::join(off_surface, " ")));
}

namespace {

// The surface point of `mesh` closest to p, its position and smooth normal.
struct SurfaceHit {
  SurfacePoint point;
  Vec3 position;
  Vec3 normal;
};

SurfaceHit HitSurface(const TriMesh& mesh, const MatX3d& normals, const Vec3& p) {
  SurfaceHit hit;
  hit.point = ClosestSurfacePoint(mesh, p);
  hit.position = EvaluateSurfacePoint(hit.point, mesh.F, mesh.V);
  hit.normal = EvaluateSurfacePoint(hit.point, mesh.F, normals).normalized();
  return hit;
}

// The rigid correction C (points x -> C x) that puts `points` on the
// surface: point-to-plane Gauss-Newton with Cauchy weights (scale 0.5 mm),
// about the points' centroid, to convergence.
Rigid3 FitToSurface(const TriMesh& mesh, const MatX3d& normals, const std::vector<Vec3>& points) {
  Rigid3 c = Rigid3::Identity();
  if (points.size() < 6) return c;
  Vec3 centre = Vec3::Zero();
  for (const Vec3& p : points) centre += p;
  centre /= static_cast<double>(points.size());
  for (int iteration = 0; iteration < 30; ++iteration) {
    Eigen::Matrix<double, 6, 6> h = Eigen::Matrix<double, 6, 6>::Identity() * 1e-6;
    Eigen::Matrix<double, 6, 1> g = Eigen::Matrix<double, 6, 1>::Zero();
    for (const Vec3& p : points) {
      const Vec3 x = c * p;
      const SurfaceHit hit = HitSurface(mesh, normals, x);
      const double r = hit.normal.dot(x - hit.position);
      const double w = 1 / (1 + (r / 0.5) * (r / 0.5));
      Eigen::Matrix<double, 6, 1> j;
      j.head<3>() = (x - centre).cross(hit.normal);
      j.tail<3>() = hit.normal;
      h += w * j * j.transpose();
      g += w * j * r;
    }
    const Eigen::Matrix<double, 6, 1> delta = -h.ldlt().solve(g);
    const Vec3 omega = delta.head<3>();
    Rigid3 step = Rigid3::Identity();
    if (omega.norm() > 0) {
      step.linear() = Eigen::AngleAxisd(omega.norm(), omega.normalized()).toRotationMatrix();
    }
    step.translation() = centre - step.linear() * centre + delta.tail<3>();
    c = step * c;
    if (delta.tail<3>().norm() < 1e-5 && omega.norm() < 1e-7) break;
  }
  return c;
}

// The names of the registered dots by the paint's own prior: the painted
// offsets are independent Gaussians, so the likeliest names are those of
// the assignment of dots to the package's markers with the least sum of
// squared offsets (Hungarian, tracking/assignment.h). The tracker names
// each dot from its 2D neighbourhood with gates made for dots on their
// marker points; a dot painted nearer a neighbour's point than its own (the
// lips' markers lie 2.6-5 mm apart) may get that name while the neighbour's
// goes unnamed or to this one's dot. A dot no marker lies within
// paint_offset_mm of keeps the tracker's name.
void RenameByPaintPrior(const Actor& package, const RegisterOptions& options,
                        RegisterOutput* out) {
  const int rows = static_cast<int>(out->registered.size());
  const int cols = static_cast<int>(package.markers.size());
  std::vector<Vec3> points(cols);
  for (int k = 0; k < cols; ++k) {
    points[k] = EvaluateSurfacePoint(package.markers[k].point, package.neutral.F, package.neutral.V);
  }
  const double gate = options.paint_offset_mm * options.paint_offset_mm;
  std::vector<AssignmentEdge> edges;
  for (int i = 0; i < rows; ++i) {
    for (int k = 0; k < cols; ++k) {
      const double cost = (out->registered[i].position - points[k]).squaredNorm();
      if (cost < gate) edges.push_back({i, k, cost});
    }
  }
  const std::vector<int> col = SolveGatedAssignment(rows, cols, edges, std::vector<double>(rows, gate));
  std::set<std::string> named;
  for (int i = 0; i < rows; ++i) {
    const int k = col[i];
    if (k < 0 || package.markers[k].name == out->registered[i].name) continue;
    const std::string was = out->registered[i].name;
    out->registered[i].name = package.markers[k].name;
    out->registered[i].offset = out->registered[i].position - points[k];
    const SurfacePoint point = out->markers[i].point;
    out->markers[i] = package.markers[k];
    out->markers[i].point = point;
    out->markers[i].vertex = -1;
    ++out->renamed;
    spdlog::info("register: the dot named {} is likelier {}'s (offset {:.2f} mm)", was,
                 package.markers[k].name, out->registered[i].offset.norm());
  }
  // Package order, and the not-found list of the names now unused.
  std::vector<int> order(rows);
  for (int i = 0; i < rows; ++i) order[i] = package.FindMarker(out->registered[i].name);
  std::vector<int> index(rows);
  for (int i = 0; i < rows; ++i) index[i] = i;
  std::sort(index.begin(), index.end(), [&](int a, int b) { return order[a] < order[b]; });
  RegisterOutput sorted = *out;
  for (int i = 0; i < rows; ++i) {
    sorted.registered[i] = out->registered[index[i]];
    sorted.markers[i] = out->markers[index[i]];
    named.insert(sorted.registered[i].name);
  }
  sorted.not_found.clear();
  for (const Marker& m : package.markers) {
    if (!named.count(m.name)) sorted.not_found.push_back(m.name);
  }
  *out = std::move(sorted);
}

// One pass's registration of the bundles (helmet space) of the markers of
// `day` (the package's, or an earlier pass's), against the package.
RegisterOutput RegisterBundles(const Actor& package, const Actor& day,
                               const std::vector<BundleFrame>& bundles_helmet,
                               const RegisterOptions& options) {
  RegisterOutput out;
  out.frames = static_cast<int>(bundles_helmet.size());
  const MarkerModel model = ComputeMarkerModel(day);
  StabilizeOptions stabilize;
  stabilize.threads = options.track.threads;
  const StabilizeOutput poses = RunStabilize(model, bundles_helmet, stabilize);
  const int num_frames = static_cast<int>(poses.frames.size());
  // Head-space positions per marker over the frames.
  std::vector<std::vector<Vec3>> positions(day.markers.size());
  for (int f = 0; f < num_frames; ++f) {
    if (!poses.frames[f].ok) continue;
    const Rigid3& head_from_helmet = poses.frames[f].head_from_helmet;
    for (const auto& [name, a] : bundles_helmet[f].bundles) {
      const int k = day.FindMarker(name);
      if (k >= 0) positions[k].push_back(head_from_helmet * a);
    }
  }
  const int needed = std::max(1, static_cast<int>(std::ceil(options.min_frames * num_frames)));
  std::vector<Vec3> means(day.markers.size(), Vec3::Zero());
  std::vector<Vec3> fitted;
  for (size_t k = 0; k < day.markers.size(); ++k) {
    if (static_cast<int>(positions[k].size()) < needed) continue;
    for (const Vec3& p : positions[k]) means[k] += p;
    means[k] /= static_cast<double>(positions[k].size());
    fitted.push_back(means[k]);
  }
  const MatX3d normals = VertexNormals(day.neutral.V, day.neutral.F);
  const Rigid3 correction = FitToSurface(day.neutral, normals, fitted);
  for (size_t k = 0; k < day.markers.size(); ++k) {
    const Marker& marker = day.markers[k];
    if (static_cast<int>(positions[k].size()) < needed) {
      out.not_found.push_back(marker.name);
      continue;
    }
    out.pose_correction_mm =
        std::max(out.pose_correction_mm, (correction * means[k] - means[k]).norm());
    const SurfaceHit hit = HitSurface(day.neutral, normals, correction * means[k]);
    RegisteredMarker r;
    r.name = marker.name;
    r.point = hit.point;
    r.position = hit.position;
    const int p = package.FindMarker(marker.name);
    r.offset = hit.position - EvaluateSurfacePoint(package.markers[p].point, package.neutral.F,
                                                   package.neutral.V);
    r.normal_mm = hit.normal.dot(correction * means[k] - hit.position);
    double spread2 = 0;
    for (const Vec3& q : positions[k]) {
      const Vec3 d = correction.linear() * (q - means[k]);
      spread2 += (d - d.dot(hit.normal) * hit.normal).squaredNorm();
    }
    r.frames = static_cast<int>(positions[k].size());
    r.motion_mm = std::sqrt(spread2 / r.frames);
    r.sigma_mm = r.motion_mm / std::sqrt(static_cast<double>(r.frames));
    if (r.motion_mm > options.loose_mm) out.loose.push_back(marker.name);
    if (std::abs(r.normal_mm) > options.off_surface_mm) out.off_surface.push_back(marker.name);
    Marker registered = package.markers[p];
    registered.point = hit.point;
    registered.vertex = -1;
    out.markers.push_back(registered);
    out.registered.push_back(r);
  }
  RenameByPaintPrior(package, options, &out);
  return out;
}

}  // namespace

RegisterOutput RunRegister(const RegisterInput& input, const RegisterOptions& options) {
  if (!options.Check()) throw InputError("invalid register options (see the message above)");
  const std::shared_ptr<const Actor> package = LoadActorForDay(input.actor, "");
  const HelmetRig rig = ReadCalibration(input.calibration);
  const TriangulateOptions triangulate;
  const ObjPolygons polygons = NeutralPolygons(*package);
  // The pass's markers: the package's, or a given start (an earlier day's).
  std::string markers_file = options.track.day.markers;
  RegisterOutput out;
  for (int pass = 1; pass <= options.passes; ++pass) {
    const fs::path dir = input.work / fmt::format("pass{}", pass);
    EnsureDirectory(dir);
    TrackOptions track = options.track;
    track.day.markers = markers_file;
    // The dots lie up to paint_offset_mm off the markers the names are
    // given from: the labelling's inlier distance (mutual matches within
    // half of it) and its triples' agreement must allow that much. From
    // pass 2 on the names come from where the dots were found.
    track.tracker.inlier_mm = std::max(track.tracker.inlier_mm, options.paint_offset_mm);
    track.tracker.triple_tolerance_mm =
        std::max(track.tracker.triple_tolerance_mm, options.paint_offset_mm);
    // A painted dot may lie nearer another marker's point than its own
    // does: the naming gate at its widest, and a dot named even where
    // another lies nearly as near (the later passes and the surface fit
    // find the names that disagree).
    track.tracker.name_gate = std::max(track.tracker.name_gate, 0.49);
    track.tracker.ambiguity_ratio = 1.01;
    TrackInput in;
    in.shot = input.shot;
    in.calibration = input.calibration;
    in.actor = input.actor;
    in.out = dir / "tracks_2d.csv";
    const TrackOutput tracks = RunTrack(in, track);
    const std::shared_ptr<const Actor> day = LoadActorForDay(input.actor, markers_file);
    const std::map<std::string, Vec3> rim =
        DotRimOffsets(*day, triangulate.dot_radius, triangulate.dot_fit_radius);
    const TriangulateOutput bundles =
        RunTriangulate({&rig, &tracks.tracks, in.out, &rim}, triangulate);
    RegisterOutput result = RegisterBundles(*package, *day, bundles.bundles, options);
    result.passes = pass;
    result.warnings = tracks.summary.warnings;
    spdlog::info("register: pass {}: {}", pass, result.BriefReport());
    out = std::move(result);
    if (out.markers.size() < 3) {
      ThrowInputError(input.shot, 0, "register: only {} markers found in the take",
                      out.markers.size());
    }
    // The next pass names the dots from where they were found; the markers
    // not found keep the package's points (a dot the labelling could not
    // name next to its neighbours' true places may be named now).
    std::vector<Marker> next = package->markers;
    for (Marker& m : next) {
      for (const Marker& found : out.markers) {
        if (found.name == m.name) m = found;
      }
    }
    markers_file = (dir / "markers.csv").string();
    WriteFileAtomic(markers_file, FormatMarkersCsv(next, &polygons));
  }
  return out;
}

std::string RegisterReportJson(const RegisterOutput& output) {
  nlohmann::json markers = nlohmann::json::array();
  for (const RegisteredMarker& r : output.registered) {
    markers.push_back({{"name", r.name},
                       {"offset_mm", {r.offset.x(), r.offset.y(), r.offset.z()}},
                       {"offset_norm_mm", r.offset.norm()},
                       {"sigma_mm", r.sigma_mm},
                       {"motion_mm", r.motion_mm},
                       {"normal_mm", r.normal_mm},
                       {"frames", r.frames}});
  }
  const nlohmann::json report = {{"frames", output.frames},
                                 {"passes", output.passes},
                                 {"pose_correction_mm", output.pose_correction_mm},
                                 {"not_found", output.not_found},
                                 {"loose", output.loose},
                                 {"off_surface", output.off_surface},
                                 {"warnings", output.warnings},
                                 {"markers", markers}};
  return report.dump(2) + "\n";
}

void WriteOffsetPicture(const Actor& actor, const RegisterOutput& output, const fs::path& png,
                        double arrow_scale) {
  const MatX3d& v = actor.neutral.V;
  const Eigen::Vector3d lo = v.colwise().minCoeff(), hi = v.colwise().maxCoeff();
  const double scale = 900 / std::max(hi.x() - lo.x(), hi.y() - lo.y());
  const int width = static_cast<int>((hi.x() - lo.x()) * scale) + 100;
  const int height = static_cast<int>((hi.y() - lo.y()) * scale) + 100;
  cv::Mat image(height, width, CV_8UC3, cv::Scalar(255, 255, 255));
  auto pixel = [&](const Vec3& p) {
    return cv::Point2d(50 + (p.x() - lo.x()) * scale, 50 + (hi.y() - p.y()) * scale);
  };
  const MatX3d normals = VertexNormals(v, actor.neutral.F);
  for (int f = 0; f < actor.neutral.NumFaces(); ++f) {
    for (int i = 0; i < 3; ++i) {
      const int a = actor.neutral.F(f, i), b = actor.neutral.F(f, (i + 1) % 3);
      if (normals(a, 2) < 0.2 || normals(b, 2) < 0.2) continue;  // seen from the front
      cv::line(image, pixel(v.row(a)), pixel(v.row(b)), cv::Scalar(225, 225, 225), 1, cv::LINE_AA);
    }
  }
  auto reported = [&](const std::string& name) {
    return std::count(output.loose.begin(), output.loose.end(), name) > 0 ||
           std::count(output.off_surface.begin(), output.off_surface.end(), name) > 0;
  };
  for (const RegisteredMarker& r : output.registered) {
    const Vec3 from = r.position - r.offset;
    const Vec3 to = from + arrow_scale * r.offset;
    const cv::Scalar colour = reported(r.name) ? cv::Scalar(30, 30, 220) : cv::Scalar(160, 90, 20);
    cv::circle(image, pixel(from), 3, cv::Scalar(60, 60, 60), cv::FILLED, cv::LINE_AA);
    cv::arrowedLine(image, pixel(from), pixel(to), colour, 2, cv::LINE_AA, 0, 0.2);
  }
  for (const std::string& name : output.not_found) {
    const int k = actor.FindMarker(name);
    if (k < 0) continue;
    const Vec3 p = EvaluateSurfacePoint(actor.markers[k].point, actor.neutral.F, v);
    cv::drawMarker(image, pixel(p), cv::Scalar(30, 30, 220), cv::MARKER_TILTED_CROSS, 14, 2);
  }
  cv::putText(image,
              fmt::format("day's markers: offsets x{:g} (red: reported; x: not found)",
                          arrow_scale),
              cv::Point(10, 25), cv::FONT_HERSHEY_SIMPLEX, 0.6, cv::Scalar(0, 0, 0), 1,
              cv::LINE_AA);
  WritePng(png, image);
}

}  // namespace hmc
