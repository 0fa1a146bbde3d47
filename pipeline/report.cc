#include "pipeline/report.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <functional>
#include <map>
#include <set>
#include <system_error>
#include <tuple>
#include <utility>

#include <Eigen/Geometry>
#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <spdlog/spdlog.h>

#include "eval/eval_metrics.h"
#include "core/actor.h"
#include "core/actor_cache.h"
#include "core/calibration.h"
#include "core/error.h"
#include "core/file_util.h"
#include "core/frame_data.h"
#include "core/image_io.h"
#include "core/mesh_sequence.h"
#include "core/render_mesh.h"
#include "core/text.h"
#include "core/tracks_2d.h"
#include "core/options.h"
#include "pipeline/run_pipeline.h"
#include "pipeline/svg_plot.h"
#include "stabilization/stabilize.h"
#include "tracking/footage_reader.h"
#include "tracking/track_eval.h"

namespace hmc {

namespace fs = std::filesystem;

void ReportOptions::Register(OptionFields* fields) {
  fields->Add("contact_frames", &contact_frames, "footage frames on the contact sheet (0 = none)")
      .In(0, 24);
  fields->Add("contact_scale", &contact_scale, "footage image scale on the contact sheet")
      .Above(0.05).AtMost(1);
  fields->Add("mesh_px", &mesh_px, "height of the mesh renders (px)").In(64, 2048);
  fields->Add("error_max_mm", &error_max_mm, "top of the error colour scale (mm)")
      .Above(0).Below(100);
}

bool ReportOptions::Check() const {
  CHECK_OPTION_LIMITS();
  return true;
}

std::string ReportWarning::Line() const { return stage + ": " + text; }

nlohmann::json ReportWarning::ToJson() const {
  return {{"stage", stage}, {"text", text}, {"markers", markers}, {"frames", frames}};
}

std::string ReportSummary::BriefReport() const {
  return fmt::format("{} stages, {} ground truth, {} warnings", stages_present,
                     has_truth ? "with" : "no", warnings.size());
}

namespace {

bool Exists(const fs::path& p) {
  std::error_code ec;
  return fs::is_regular_file(p, ec);
}

std::string ImgTag(const cv::Mat& image, const std::string& alt) {
  std::vector<uchar> png;
  cv::imencode(".png", image, png);
  return fmt::format("<img alt=\"{}\" src=\"data:image/png;base64,{}\">", HtmlEscape(alt), Base64Encode(png.data(), png.size()));
}

double Percentile(std::vector<double> v, double q) {
  if (v.empty()) return std::nan("");
  const size_t k = std::min(v.size() - 1, static_cast<size_t>(std::ceil(q * v.size())) - (q > 0));
  std::nth_element(v.begin(), v.begin() + k, v.end());
  return v[k];
}

double Rms(const std::vector<double>& v) {
  if (v.empty()) return std::nan("");
  double s = 0;
  for (double x : v) s += x * x;
  return std::sqrt(s / v.size());
}

// A JSON object's scalars as "key: value" cells, nested one level.
std::string SummaryCells(const nlohmann::json& j, int depth = 0) {
  if (!j.is_object()) return "";
  std::string out;
  for (const auto& [k, v] : j.items()) {
    if (k == "run_inputs") continue;  // the same for every stage
    if (v.is_object() && depth < 1) {
      out += SummaryCells(v, depth + 1);
    } else if (v.is_number_float()) {
      out += fmt::format("<span class=kv>{}: {:.4g}</span> ", HtmlEscape(k), v.get<double>());
    } else if (v.is_primitive()) {
      out += fmt::format("<span class=kv>{}: {}</span> ", HtmlEscape(k), HtmlEscape(v.dump()));
    }
  }
  return out;
}

// Sorted frame numbers as runs: "3, 7-9, 12".
std::string FrameRuns(const std::vector<int>& frames) {
  std::string text;
  for (size_t i = 0; i < frames.size();) {
    size_t j = i;
    while (j + 1 < frames.size() && frames[j + 1] == frames[j] + 1) ++j;
    text += (text.empty() ? "" : ", ") +
            (j == i ? std::to_string(frames[i]) : fmt::format("{}-{}", frames[i], frames[j]));
    i = j + 1;
  }
  return text;
}

// A list of bad frames ([{frame, reason}]) as warnings: one line per reason
// with the frames it concerns ("stabilize: frames 3, 7-9 interpolated: ...").
void FrameListWarnings(const nlohmann::json& list, const std::string& stage, const char* what,
                       std::vector<ReportWarning>* out) {
  std::map<std::string, std::vector<int>> by_reason;
  for (const auto& f : list) {
    if (f.is_object()) by_reason[f.value("reason", std::string())].push_back(f.value("frame", 0));
  }
  for (auto& [reason, frames] : by_reason) {
    std::sort(frames.begin(), frames.end());
    out->push_back({stage,
                    fmt::format("{} {} {}: {}", frames.size() == 1 ? "frame" : "frames",
                                FrameRuns(frames), what, reason),
                    {},
                    frames});
  }
}

// Rotation angle of `r` (deg), through the quaternion: exact near 0, where
// acos((trace - 1) / 2) loses half the digits.
double RotationDeg(const Mat3& r) {
  return Eigen::AngleAxisd(Eigen::Quaterniond(r).normalized()).angle() * 180 / M_PI;
}

class ReportWriter {
 public:
  ReportWriter(const ReportInput& input, const ReportOptions& options)
      : in_(input), options_(options), work_(input.work), shot_(input.shot) {}

  ReportSummary Write();

 private:
  fs::path Stage(const std::string& stage, const std::string& file) const {
    return work_ / stage / file;
  }
  void Section(const std::string& title) { html_ += "<h2>" + HtmlEscape(title) + "</h2>\n"; }
  // An SVG plot on the page, its data in plots.json.
  void Plot(const std::vector<PlotSeries>& series, PlotOptions o);
  void Note(const std::string& text) { html_ += "<p>" + text + "</p>\n"; }

  void StageTable();
  // A stage summary's `warnings`, its lists of bad frames
  // (`flagged_frames`, `interpolated_frames`), stabilize's `bad_tracks`
  // and triangulate's `gated_list`, at any depth.
  void CollectWarnings(const nlohmann::json& j, const std::string& stage);
  // Stabilize's bad tracks, each with the frames where its residual
  // exceeds the stage's `bad_track_mm` (residuals.csv).
  void BadTrackWarnings(const nlohmann::json& bad_tracks);
  // The marker-frames the triangulation dropped (triangulation.csv rows
  // not `ok`: gated, inconsistent, ...): one warning per marker and
  // reason, the most frames first.
  void TriangulationWarnings();
  void TrackSection();
  void TriangulateSection();
  void StabilizeSection();
  void JawSection();
  void SolveSection(const Actor& actor);
  void ContactSheet(const Actor& actor);
  // One footage panel of the contact sheet: `grey` (8-bit, the crop's
  // picture at any size) scaled to mesh_px rows, as `crop` (full-image px)
  // at `scale` (panel px per image px), with the frame's named dots.
  cv::Mat FootagePanel(const cv::Mat& grey, const cv::Rect& crop, double scale, int frame,
                       const std::string& camera) const;
  // The footage panels of the chosen frames, per frame one per camera in
  // `names` order, from the track stage's proxies; false when they do not
  // hold every one.
  bool ProxyFootage(const std::set<int>& chosen, const std::vector<std::string>& names,
                    std::map<int, std::vector<cv::Mat>>* panels) const;
  // The contact sheet's frames, spread evenly over the reconstruction.
  std::set<int> ContactFrames() const;

  ReportInput in_;
  ReportOptions options_;
  fs::path work_, shot_;
  std::string html_;
  ReportSummary summary_;
  std::map<std::tuple<int, std::string, std::string>, Vec2> named_;  // (frame, camera, marker) -> px
  std::vector<Track2d> tracks_;
  MeshSequence recon_;
  std::map<int, Eigen::VectorXd> vertex_error_;  // contact frame -> per-vertex error (mm)
};

void ReportWriter::Plot(const std::vector<PlotSeries>& series, PlotOptions o) {
  html_ += SvgLinePlot(series, o) + "\n";
  nlohmann::json plot = {{"title", o.title},
                         {"x_label", o.x_label},
                         {"y_label", o.y_label},
                         {"y_from_zero", o.y_from_zero},
                         {"series", nlohmann::json::array()}};
  for (const PlotSeries& s : series) {
    nlohmann::json points = nlohmann::json::array();
    for (const auto& [x, y] : s.points) {
      // Non-finite values break the line: null in JSON.
      nlohmann::json point = nlohmann::json::array();
      point.push_back(x);
      if (std::isfinite(y)) {
        point.push_back(y);
      } else {
        point.push_back(nullptr);
      }
      points.push_back(std::move(point));
    }
    plot["series"].push_back({{"name", s.name}, {"points", points}});
  }
  summary_.plots.push_back(plot);
}

void ReportWriter::CollectWarnings(const nlohmann::json& j, const std::string& stage) {
  if (!j.is_object()) return;
  for (const auto& [k, v] : j.items()) {
    if (k == "warnings" && v.is_array()) {
      for (const auto& w : v) {
        summary_.warnings.push_back({stage, w.is_string() ? w.get<std::string>() : w.dump(), {}, {}});
      }
    } else if ((k == "flagged_frames" || k == "interpolated_frames") && v.is_array()) {
      FrameListWarnings(v, stage, k == "flagged_frames" ? "flagged" : "interpolated",
                        &summary_.warnings);
    } else if (k == "bad_tracks" && v.is_array()) {
      BadTrackWarnings(v);
    } else if (k == "gated_list") {
      // Listed from triangulation.csv with the other dropped rows
      // (TriangulationWarnings).
    } else {
      CollectWarnings(v, stage);
    }
  }
}

void ReportWriter::BadTrackWarnings(const nlohmann::json& bad_tracks) {
  if (bad_tracks.empty()) return;
  double threshold = StabilizeOptions().bad_track_mm;
  const fs::path used = Stage("stabilize", "options_used.yaml");
  if (Exists(used)) {
    const YAML::Node node = LoadYamlFile(used.string());
    if (node["bad_track_mm"]) threshold = node["bad_track_mm"].as<double>();
  }
  std::map<std::string, std::vector<int>> over;  // marker -> frames over the threshold
  const fs::path residuals = Stage("stabilize", "residuals.csv");
  if (Exists(residuals)) {
    ForEachCsvRow(residuals, {"frame", "marker", "residual_mm", "weight"},
                  [&](const CsvRow& row) {
                    if (row.Finite(2) > threshold) over[row.Text(1)].push_back(row.Int(0));
                  });
  }
  for (const auto& b : bad_tracks) {
    const std::string marker = b.value("marker", std::string());
    std::vector<int>& frames = over[marker];
    std::sort(frames.begin(), frames.end());
    summary_.warnings.push_back(
        {"stabilize",
         fmt::format("track of {} flagged: median residual {:.2f} mm over {} mm{}", marker,
                     b.value("median_residual_mm", 0.0), threshold,
                     frames.empty() ? "" : fmt::format(", over it at frames {}", FrameRuns(frames))),
         {marker},
         frames});
  }
}

void ReportWriter::TriangulationWarnings() {
  const fs::path file = Stage("triangulate", "triangulation.csv");
  if (!Exists(file)) return;
  std::map<std::pair<std::string, std::string>, std::vector<int>> dropped;  // (marker, status) -> frames
  const std::string text = ReadFile(file);
  bool header = true;
  ForEachLine(text, [&](int line, std::string_view l) {
    if (Trim(l).empty()) return;
    if (std::exchange(header, false)) return;
    const std::vector<std::string> f = SplitCsvRecord(l, file, line);
    int frame = 0;
    if (f.size() < 3 || !ParseInt(f[0], &frame)) ThrowInputError(file, line, "expected frame,marker,status,...");
    if (f[2] != "ok") dropped[{f[1], f[2]}].push_back(frame);
  });
  std::vector<std::pair<std::pair<std::string, std::string>, std::vector<int>>> sorted(dropped.begin(),
                                                                                        dropped.end());
  std::stable_sort(sorted.begin(), sorted.end(),
                   [](const auto& a, const auto& b) { return a.second.size() > b.second.size(); });
  for (auto& [key, frames] : sorted) {
    std::sort(frames.begin(), frames.end());
    const std::string why = key.second == "gated"          ? "a view's residual over the gate: a wrong name or a bad detection"
                            : key.second == "inconsistent" ? "the views' rays miss by more than the pixel noise explains"
                                                           : key.second;
    summary_.warnings.push_back({"triangulate",
                                 fmt::format("{} dropped ({}) at {} {} ({})", key.first, key.second,
                                             frames.size() == 1 ? "frame" : "frames", FrameRuns(frames), why),
                                 {key.first},
                                 frames});
  }
}

void ReportWriter::StageTable() {
  Section("Stages");
  html_ += "<table><tr><th>stage</th><th>state</th><th>time</th><th>summary</th></tr>\n";
  for (const std::string& stage : PipelineStages()) {
    if (stage == "report") continue;
    const fs::path file = Stage(stage, "summary.json");
    if (!Exists(file)) {
      html_ += fmt::format("<tr><td>{}</td><td class=bad>missing</td><td></td><td></td></tr>\n", stage);
      continue;
    }
    ++summary_.stages_present;
    nlohmann::json s;
    try {
      s = nlohmann::json::parse(ReadFile(file));
    } catch (const std::exception& e) {
      ThrowInputError(file, 0, "not JSON: {}", e.what());
    }
    CollectWarnings(s, stage);
    const nlohmann::json report = s.value("report", nlohmann::json::object());
    const bool skipped = report.contains("skipped");
    std::string cells = SummaryCells(report);
    if (cells.empty()) {
      // A stage whose command writes no summary of its own (calibrate's
      // is report.json, the solve's diagnostics.json): what it wrote.
      const nlohmann::json outputs = s.value("outputs", nlohmann::json::object());
      for (const auto& [file, hash] : outputs.items()) {
        std::error_code ec;
        const auto bytes = fs::file_size(work_ / stage / file, ec);
        cells += fmt::format("<span class=kv>{} ({})</span> ", HtmlEscape(file),
                             ec ? std::string("missing") : fmt::format("{:.1f} kB", bytes / 1e3));
      }
      if (cells.empty()) cells = "no outputs recorded";
    }
    html_ += fmt::format("<tr><td>{}</td><td>{}</td><td>{:.1f} s</td><td>{}</td></tr>\n", stage,
                         skipped ? "skipped: " + HtmlEscape(report["skipped"].get<std::string>()) : "done",
                         s.value("seconds", 0.0), cells);
  }
  html_ += "</table>\n";
}

void ReportWriter::TrackSection() {
  const fs::path file = Stage("track", "tracks_2d.csv");
  if (!Exists(file)) return;
  Section("Track");
  tracks_ = ReadTracks2dCsv(file);
  std::map<std::string, std::map<int, int>> per_camera;  // camera -> frame -> named dots
  for (const Track2d& t : tracks_) {
    ++per_camera[t.camera][t.frame];
    named_[{t.frame, t.camera, t.marker}] = t.pixel;
  }
  std::vector<PlotSeries> series;
  for (const auto& [camera, counts] : per_camera) {
    PlotSeries s{camera, {}};
    for (const auto& [f, n] : counts) s.points.emplace_back(f, n);
    series.push_back(s);
  }
  Plot(series, {"named dots per frame", "frame", "dots", 640, 220, true});
  const fs::path truth_file = shot_ / "dots_2d.csv";
  if (!Exists(truth_file)) return;
  // Against the shot's ground truth, scored as `hmc eval-tracks` scores it.
  const TrackScore score = ScoreTracks(tracks_, ReadDots2dCsv(truth_file));
  PlotSeries median{"median", {}}, p95{"p95", {}};
  for (const auto& [f, e] : score.full_errors_by_frame) {
    median.points.emplace_back(f, Percentile(e, 0.5));
    p95.points.emplace_back(f, Percentile(e, 0.95));
  }
  Plot({median, p95}, {"dot centre error against the truth (full dots)", "frame", "px", 640, 220, true});
  summary_.accuracy["track"] = {{"full_dot_error_median_px", score.median_px},
                                {"full_dot_error_p95_px", score.p95_px},
                                {"full_named_fraction", score.FullRecall()},
                                {"partial_named_fraction", score.PartialRecall()},
                                {"wrong_names", score.wrong},
                                {"rows_on_hidden_dots", score.hidden_rows}};
  Note("Against the ground truth (as `hmc eval-tracks` scores it): " + score.BriefReport() + ".");
}

void ReportWriter::TriangulateSection() {
  const fs::path file = Stage("triangulate", "bundles_helmet.csv");
  if (!Exists(file)) return;
  Section("Triangulate");
  const std::vector<BundleFrame> bundles = ReadBundlesCsv(file);
  PlotSeries count{"bundles", {}};
  for (const BundleFrame& f : bundles) count.points.emplace_back(f.frame, f.bundles.size());
  Plot({count}, {"triangulated bundles per frame", "frame", "bundles", 640, 220, true});
  const fs::path truth_file = shot_ / "bundles_helmet.csv";
  if (!Exists(truth_file)) return;
  std::map<int, const BundleFrame*> truth;
  const std::vector<BundleFrame> truth_frames = ReadBundlesCsv(truth_file);
  for (const BundleFrame& f : truth_frames) truth[f.frame] = &f;
  std::vector<double> all;
  PlotSeries rms{"rms", {}};
  for (const BundleFrame& f : bundles) {
    const auto t = truth.find(f.frame);
    if (t == truth.end()) continue;
    std::vector<double> e;
    for (const auto& [marker, p] : f.bundles) {
      const auto m = t->second->bundles.find(marker);
      if (m != t->second->bundles.end()) e.push_back((p - m->second).norm());
    }
    all.insert(all.end(), e.begin(), e.end());
    rms.points.emplace_back(f.frame, Rms(e));
  }
  Plot({rms}, {"bundle error against the truth (helmet space)", "frame", "mm", 640, 220, true});
  summary_.accuracy["triangulate"] = {{"bundle_error_median_mm", Percentile(all, 0.5)},
                                      {"bundle_error_rms_mm", Rms(all)},
                                      {"bundle_error_p99_mm", Percentile(all, 0.99)}};
  Note(fmt::format("Against the ground truth: median {:.3f} mm, RMS {:.3f} mm, p99 {:.3f} mm over {} bundles.",
                   Percentile(all, 0.5), Rms(all), Percentile(all, 0.99), all.size()));
}

void ReportWriter::StabilizeSection() {
  const fs::path file = Stage("stabilize", "head_from_helmet.csv");
  if (!Exists(file)) return;
  Section("Stabilize");
  const std::vector<PoseFrame> poses = ReadPosesCsv(file);
  if (poses.empty()) return;
  PlotSeries t{"translation (mm)", {}}, r{"rotation (deg)", {}};
  for (const PoseFrame& p : poses) {
    const Rigid3 d = p.pose * poses.front().pose.inverse();
    t.points.emplace_back(p.frame, d.translation().norm());
    r.points.emplace_back(p.frame, RotationDeg(d.linear()));
  }
  Plot({t, r}, {"head motion in the helmet since the first frame", "frame", "mm / deg", 640, 220, true});
  const fs::path truth_file = shot_ / "head_from_helmet.csv";
  if (!Exists(truth_file)) return;
  std::map<int, Rigid3> truth;
  for (const PoseFrame& p : ReadPosesCsv(truth_file)) truth[p.frame] = p.pose;
  std::vector<double> te, re;
  PlotSeries et{"translation (mm)", {}}, er{"rotation (deg)", {}};
  for (const PoseFrame& p : poses) {
    const auto it = truth.find(p.frame);
    if (it == truth.end()) continue;
    te.push_back((p.pose.translation() - it->second.translation()).norm());
    re.push_back(RotationDeg(p.pose.linear() * it->second.linear().transpose()));
    et.points.emplace_back(p.frame, te.back());
    er.points.emplace_back(p.frame, re.back());
  }
  Plot({et, er}, {"head pose error against the truth", "frame", "mm / deg", 640, 220, true});
  summary_.accuracy["stabilize"] = {{"translation_rms_mm", Rms(te)}, {"rotation_rms_deg", Rms(re)}};
  Note(fmt::format("Against the ground truth: translation RMS {:.3f} mm, rotation RMS {:.4f} deg.",
                   Rms(te), Rms(re)));
}

void ReportWriter::JawSection() {
  const fs::path file = Stage("jaw", "jaw.csv");
  if (!Exists(file)) return;
  Section("Jaw");
  const std::vector<JawFrame> jaw = ReadJawCsv(file);
  std::map<int, JawPose> truth;
  if (Exists(shot_ / "jaw.csv")) {
    for (const JawFrame& j : ReadJawCsv(shot_ / "jaw.csv")) truth[j.frame] = j.pose;
  }
  const auto& names = JawPose::ParameterNames();
  nlohmann::json accuracy;
  for (size_t i = 0; i < names.size(); ++i) {
    PlotSeries est{"estimated", {}}, tru{"truth", {}};
    std::vector<double> e;
    for (const JawFrame& j : jaw) {
      est.points.emplace_back(j.frame, j.pose.ToArray()[i]);
      const auto it = truth.find(j.frame);
      if (it != truth.end()) {
        tru.points.emplace_back(j.frame, it->second.ToArray()[i]);
        e.push_back(j.pose.ToArray()[i] - it->second.ToArray()[i]);
      }
    }
    Plot({est, tru}, {names[i], "frame", names[i], 640, 180, false});
    if (!e.empty()) accuracy[names[i] + "_rms"] = Rms(e);
  }
  if (!accuracy.is_null()) {
    summary_.accuracy["jaw"] = accuracy;
    Note("Against the ground truth (RMS): " + SummaryCells(accuracy));
  }
}

void ReportWriter::SolveSection(const Actor& actor) {
  const fs::path file = Stage("solve", "mesh.pc2");
  if (!Exists(file)) return;
  Section("Solve");
  if (Exists(shot_ / "truth.pc2")) {
    recon_ = ReadMeshSequence(file, &actor.neutral);  // every frame, against the truth
  } else {
    // Only the contact sheet's frames: a long shot's mesh is not held.
    MeshSequenceReadOptions read;
    read.topology = &actor.neutral;
    read.wanted = [](int) { return false; };
    recon_ = ReadMeshSequence(file, read);  // the frame numbers
    const std::set<int> contact = ContactFrames();
    read.wanted = [&contact](int f) { return contact.count(f) > 0; };
    recon_ = ReadMeshSequence(file, read);
  }
  const fs::path diag = Stage("solve", "diagnostics.json");
  if (Exists(diag)) {
    PlotSeries outside{"outside their data (%)", {}}, residual{"mean residual (0.01 mm)", {}};
    nlohmann::json flagged = nlohmann::json::array();
    ForEachSolveFrame(diag, [&](const nlohmann::json& f) {
      const int frame = f.value("frame", 0);
      if (!f.value("ok", false)) {
        flagged.push_back({{"frame", frame}, {"reason", f.value("reason", std::string())}});
        return;
      }
      int n = 0, projected = 0;
      double res = 0;
      for (const auto& b : f.value("bundles", nlohmann::json::array())) {
        if (b.value("status", std::string()) == "filled") continue;
        ++n;
        projected += b.value("status", std::string()) == "projected";
        res += b.value("residual_mm", 0.0);
      }
      if (n > 0) {
        outside.points.emplace_back(frame, 100.0 * projected / n);
        residual.points.emplace_back(frame, 100.0 * res / n);
      }
    });
    FrameListWarnings(flagged, "solve", "flagged", &summary_.warnings);
    Plot({outside, residual}, {"solve: bundles outside their data, bundle residual", "frame", "", 640, 220, true});
  }
  if (!Exists(shot_ / "truth.pc2")) return;
  // The truth's frames are moved into t and the reconstruction's lent to r
  // (and given back after), not copied: the report holds the two
  // sequences once each whatever the shot's length, and per-vertex errors
  // only for the contact sheet's frames.
  MeshSequence truth = ReadMeshSequence(shot_ / "truth.pc2", &actor.neutral);
  const std::set<int> contact = ContactFrames();
  std::vector<MatX3d> t, r;
  std::vector<int> numbers;
  std::vector<size_t> lent;
  for (size_t i = 0; i < recon_.frames.size(); ++i) {
    const int frame = recon_.start_frame + static_cast<int>(i);
    const int ti = frame - truth.start_frame;
    if (ti < 0 || ti >= static_cast<int>(truth.frames.size())) continue;
    t.push_back(std::move(truth.frames[ti]));
    r.push_back(std::move(recon_.frames[i]));
    lent.push_back(i);
    numbers.push_back(frame);
    if (contact.count(frame)) vertex_error_[frame] = VertexErrors(t.back(), r.back());
  }
  truth.frames.clear();
  truth.frames.shrink_to_fit();
  if (numbers.empty()) return;
  const SequenceEvaluator evaluator(actor, MeshMetricsOptions{});
  const SequenceMetrics m = evaluator.Evaluate(t, r, numbers, nullptr);
  t.clear();
  t.shrink_to_fit();
  for (size_t j = 0; j < lent.size(); ++j) recon_.frames[lent[j]] = std::move(r[j]);
  PlotSeries mean{"face mean", {}}, p95{"face p95", {}};
  for (const FrameMetrics& f : m.per_frame) {
    mean.points.emplace_back(f.frame, f.face.mean);
    p95.points.emplace_back(f.frame, f.face.p95);
  }
  Plot({mean, p95}, {"mesh error against the truth (face region)", "frame", "mm", 640, 220, true});
  summary_.accuracy["solve"] = {{"face_mean_mm", m.face.mean},   {"face_p95_mm", m.face.p95},
                                {"face_max_mm", m.face.max},     {"all_mean_mm", m.all.mean},
                                {"detail_face_mm", m.detail_face}, {"flicker_face", m.flicker_face.mean},
                                {"frames", m.frames}};
  Note(fmt::format("Against the ground truth: face mean {:.4f} mm, p95 {:.4f} mm, max {:.3f} mm over {} "
                   "frames.",
                   m.face.mean, m.face.p95, m.face.max, m.frames));
  MeshRenderOptions render;
  render.height = options_.mesh_px * 2;
  render.width = options_.mesh_px * 8 / 5;
  const cv::Mat heat = WithColorBar(
      RenderMeshScalars(actor.neutral, m.mean_vertex_error, 0, options_.error_max_mm,
                        ColorMap::kViridis, render),
      ColorMap::kViridis, 0, options_.error_max_mm, "mm");
  WritePng(fs::path(in_.out) / "mesh_error.png", heat);
  html_ += "<p>Mean error per vertex over the shot, on the neutral:</p>" + ImgTag(heat, "mean error") + "\n";
}

std::set<int> ReportWriter::ContactFrames() const {
  std::set<int> chosen;
  if (options_.contact_frames == 0 || recon_.frames.empty()) return chosen;
  const int first = recon_.start_frame;
  const int last = first + static_cast<int>(recon_.frames.size()) - 1;
  const int k = options_.contact_frames;
  for (int i = 0; i < k; ++i) chosen.insert(first + (last - first) * (2 * i + 1) / (2 * k));
  return chosen;
}

// The footage panel of one camera's frame: the image cropped to `crop`
// (full-image px), `rows` tall, with the frame's named dots circled.
cv::Mat ReportWriter::FootagePanel(const cv::Mat& grey, const cv::Rect& crop, double scale, int frame,
                                   const std::string& camera) const {
  cv::Mat bgr;
  cv::cvtColor(grey, bgr, cv::COLOR_GRAY2BGR);
  const cv::Size size(std::max(1, static_cast<int>(std::lround(crop.width * scale))),
                      options_.mesh_px);
  if (bgr.size() != size) {
    cv::resize(bgr, bgr, size, 0, 0, bgr.rows > size.height ? cv::INTER_AREA : cv::INTER_LINEAR);
  }
  for (const auto& [key, px] : named_) {
    if (std::get<0>(key) != frame || std::get<1>(key) != camera) continue;
    const cv::Point2d p((px.x() - crop.x + 0.5) * scale - 0.5, (px.y() - crop.y + 0.5) * scale - 0.5);
    cv::circle(bgr, p, 3, cv::Scalar(80, 220, 80), 1, cv::LINE_AA);
  }
  return bgr;
}

bool ReportWriter::ProxyFootage(const std::set<int>& chosen, const std::vector<std::string>& names,
                                std::map<int, std::vector<cv::Mat>>* panels) const {
  const fs::path dir = Stage("track", "proxies");
  if (!Exists(dir / "proxies.json")) return false;
  nlohmann::json p;
  try {
    p = nlohmann::json::parse(ReadFile(dir / "proxies.json"));
  } catch (const std::exception&) {
    return false;  // decode the footage instead
  }
  std::map<std::string, nlohmann::json> by_name;
  for (const auto& c : p.value("cameras", nlohmann::json::array())) by_name[c.value("name", "")] = c;
  for (const std::string& name : names) {
    const auto cam = by_name.find(name);
    if (cam == by_name.end()) return false;
    const std::vector<int> crop = cam->second.value("crop", std::vector<int>{});
    if (crop.size() != 4 || crop[3] <= 0) return false;
    const cv::Rect rect(crop[0], crop[1], crop[2], crop[3]);
    const double scale = static_cast<double>(options_.mesh_px) / rect.height;
    for (const int f : chosen) {
      const cv::Mat grey = cv::imread((dir / name / fmt::format("{:06d}.jpg", f)).string(),
                                      cv::IMREAD_GRAYSCALE);
      if (grey.empty()) return false;
      (*panels)[f].push_back(FootagePanel(grey, rect, scale, f, name));
    }
  }
  return true;
}

void ReportWriter::ContactSheet(const Actor& actor) {
  const std::set<int> chosen = ContactFrames();
  if (chosen.empty()) return;
  std::vector<std::string> names = {"cam0", "cam1"};
  const fs::path cal = Stage("calibrate", "calibration.yaml");
  if (Exists(cal)) names = ReadCalibration(cal).CameraNames();
  // The footage panels: the track stage's proxies, made as it decoded the
  // footage (issue 46: the report decodes nothing again), else decoded
  // here (a workspace tracked without proxies).
  std::map<int, std::vector<cv::Mat>> footage_panels;
  if (!ProxyFootage(chosen, names, &footage_panels)) {
    footage_panels.clear();
    FootageOptions footage;
    footage.frames = fmt::format("{}:{}", *chosen.begin(), *chosen.rbegin());
    try {
      FootageReader reader(shot_, names, footage);
      FootageFrame frame;
      // The frames between are passed over, not turned into images.
      while (reader.Next(&frame, [&chosen](int f) { return chosen.count(f) > 0; })) {
        for (int c = 0; c < reader.num_cameras(); ++c) {
          // Framed on the camera's named dots over the shot (the fisheye
          // sees far more than the face), so the dots can be told apart.
          const cv::Rect crop = NamedDotsBox(tracks_, names[c], reader.image_size(c));
          const double scale = static_cast<double>(options_.mesh_px) / crop.height;
          if (frame.images[c].empty()) {
            footage_panels[frame.frame].push_back(
                cv::Mat(cv::Size(std::lround(crop.width * scale), options_.mesh_px), CV_8UC3,
                        cv::Scalar(40, 40, 90)));
          } else {
            footage_panels[frame.frame].push_back(
                FootagePanel(ToGrey8(frame.images[c])(crop), crop, scale, frame.frame, names[c]));
          }
        }
      }
    } catch (const InputError& e) {
      summary_.warnings.push_back({"report", std::string("no contact sheet: ") + e.what(), {}, {}});
      return;
    }
  }
  std::vector<cv::Mat> rows;
  MeshRenderOptions render;
  render.height = options_.mesh_px;
  render.width = options_.mesh_px * 4 / 5;
  for (auto& [f, panels] : footage_panels) {
    std::vector<std::string> labels;
    for (const std::string& name : names) labels.push_back(fmt::format("frame {} {}", f, name));
    const int i = f - recon_.start_frame;
    TriMesh mesh = actor.neutral;
    mesh.V = recon_.frames[i];
    panels.push_back(RenderMesh(mesh, render));
    labels.push_back("reconstruction");
    const auto err = vertex_error_.find(f);
    if (err != vertex_error_.end()) {
      panels.push_back(RenderMeshScalars(mesh, err->second, 0, options_.error_max_mm,
                                         ColorMap::kViridis, render));
      labels.push_back(fmt::format("error, 0-{} mm", options_.error_max_mm));
    }
    rows.push_back(ComposeLabelledPanels(panels, labels));
  }
  if (rows.empty()) return;
  int width = 0;
  for (const cv::Mat& r : rows) width = std::max(width, r.cols);
  for (cv::Mat& r : rows) {
    if (r.cols < width) cv::copyMakeBorder(r, r, 0, 0, 0, width - r.cols, cv::BORDER_CONSTANT, cv::Scalar(38, 38, 38));
  }
  cv::Mat sheet;
  cv::vconcat(rows, sheet);
  WritePng(fs::path(in_.out) / "contact_sheet.png", sheet);
  Section("Contact sheet");
  html_ += ImgTag(sheet, "contact sheet") + "\n";
}

ReportSummary ReportWriter::Write() {
  const std::shared_ptr<const Actor> loaded = LoadActorShared(in_.actor);
  const Actor& actor = *loaded;
  EnsureDirectory(in_.out);
  summary_.has_truth = Exists(shot_ / "truth.pc2") || Exists(shot_ / "dots_2d.csv");
  StageTable();
  TriangulationWarnings();
  TrackSection();
  TriangulateSection();
  StabilizeSection();
  JawSection();
  SolveSection(actor);
  ContactSheet(actor);
  std::string warnings = "<h2>Warnings</h2>\n";
  if (summary_.warnings.empty()) warnings += "<p>none</p>\n";
  warnings += "<ul>\n";
  nlohmann::json warning_list = nlohmann::json::array();
  for (const ReportWarning& w : summary_.warnings) {
    warnings += "<li>" + HtmlEscape(w.Line()) + "</li>\n";
    warning_list.push_back(w.ToJson());
  }
  warnings += "</ul>\n";
  std::string page = fmt::format(
      "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>hmc run report: {}</title>\n"
      "<style>body{{font-family:sans-serif;max-width:1400px;margin:1em auto;color:#222}}"
      "table{{border-collapse:collapse}}td,th{{border:1px solid #ccc;padding:3px 6px;text-align:left;"
      "vertical-align:top;font-size:13px}}.kv{{display:inline-block;margin-right:.8em}}"
      ".bad{{color:#b00}}img{{max-width:100%}}svg{{margin:4px}}</style></head><body>\n"
      "<h1>hmc run report</h1>\n<p>workspace <code>{}</code>, shot <code>{}</code>, actor "
      "<code>{}</code>{}</p>\n",
      HtmlEscape(fs::path(in_.work).filename().string()), HtmlEscape(in_.work), HtmlEscape(in_.shot),
      HtmlEscape(actor.name), summary_.has_truth ? " (ground truth present)" : "");
  page += warnings + html_ + "</body></html>\n";
  WriteFileAtomic(fs::path(in_.out) / "report.html", page);
  WriteFileAtomic(fs::path(in_.out) / "plots.json",
                  nlohmann::json{{"plots", summary_.plots}, {"warnings", warning_list}}.dump() + "\n");
  if (!summary_.accuracy.is_null()) {
    WriteFileAtomic(fs::path(in_.out) / "accuracy.json", summary_.accuracy.dump(1) + "\n");
  }
  return summary_;
}

}  // namespace

void ForEachSolveFrame(const fs::path& diagnostics, const std::function<void(const nlohmann::json&)>& body) {
  // Each frame's record is used as the parser completes it, then dropped:
  // the file grows with the shot (800 MB for 2,000 frames of a small
  // actor), its parsed tree would be several times that.
  auto frame_done = [&](int, nlohmann::json::parse_event_t event, nlohmann::json& f) {
    if (event != nlohmann::json::parse_event_t::object_end || !f.contains("frame") || !f.contains("bundles")) {
      return true;
    }
    body(f);
    return false;
  };
  std::ifstream in(diagnostics);
  try {
    const nlohmann::json rest = nlohmann::json::parse(in, frame_done);  // the frames dropped
    (void)rest;
  } catch (const nlohmann::json::exception& e) {
    ThrowInputError(diagnostics, 0, "not JSON: {}", e.what());
  }
}

cv::Rect NamedDotsBox(const std::vector<Track2d>& tracks, const std::string& camera, cv::Size size) {
  double x0 = 1e30, y0 = 1e30, x1 = -1e30, y1 = -1e30;
  for (const Track2d& t : tracks) {
    if (t.camera != camera) continue;
    x0 = std::min(x0, t.pixel.x());
    y0 = std::min(y0, t.pixel.y());
    x1 = std::max(x1, t.pixel.x());
    y1 = std::max(y1, t.pixel.y());
  }
  const cv::Rect whole(0, 0, size.width, size.height);
  if (x0 > x1) return whole;
  const double margin = 0.12 * std::max(x1 - x0, y1 - y0) + 10;
  const cv::Rect box(cv::Point(static_cast<int>(x0 - margin), static_cast<int>(y0 - margin)),
                     cv::Point(static_cast<int>(x1 + margin), static_cast<int>(y1 + margin)));
  const cv::Rect clipped = box & whole;
  return clipped.area() > 0 ? clipped : whole;
}


ReportSummary WriteRunReport(const ReportInput& input, const ReportOptions& options) {
  return ReportWriter(input, options).Write();
}

}  // namespace hmc
