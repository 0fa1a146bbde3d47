#include "tracking/track_shot.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <set>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <spdlog/spdlog.h>

#include "core/actor.h"
#include "core/calibration.h"
#include "core/error.h"
#include "core/file_util.h"
#include "core/image_io.h"
#include "core/logging.h"
#include "core/parallel.h"
#include "tracking/overlay.h"
#include "tracking/track_fixes.h"

namespace hmc {

void TrackOptions::Register(OptionFields* fields) {
  footage.Register(fields);
  footage.RegisterTransfer(fields);
  fields->Add("reference_frame", &reference_frame,
              "frame where the actor is near neutral and names are given")
      .AtLeast(1);
  fields->Add("threads", &threads, "worker threads (0 = all cores)").AtLeast(0);
  day.Register(fields);
  fields->SetGroup("detect");
  detect.Register(fields);
  fields->SetGroup("track");
  tracker.Register(fields);
  fields->SetGroup("");
}

bool TrackOptions::Check() const {
  CHECK_OPTION_LIMITS();
  return footage.Check() && detect.Check() && tracker.Check();
}

std::string TrackSummary::BriefReport() const {
  return fmt::format(
      "{} frames from reference frame {} ({} markers registered, rms {:.2f} mm); {:.1f} "
      "detections and {:.1f} named dots per view; {} re-acquired, {} swaps caught, {} views "
      "skipped; {} rows in {:.1f} s ({:.1f} camera-frames/s)",
      frames, reference_frame, labelling.inliers, labelling.rms_mm, mean_detections, mean_named,
      reacquired, swaps_caught, skipped_views, rows, seconds,
      seconds > 0 ? 2 * frames / seconds : 0.0);
}

namespace {

// Exposure changing over the shot (auto-exposure, a light dimming): the
// linear frame scaled back to the reference frame's level (its mean), into
// 16 bits, when the two differ by more than 3 %. In linear light an
// exposure change is a gain; undone, the detector's absolute thresholds
// (min_step, in fractions of full scale) and the optical flow's
// brightness constancy hold as at the reference frame
// (docs/tracking.md, "Images"). Returns the gain applied (1: none).
double FullScale(const cv::Mat& image) { return image.depth() == CV_16U ? 65535.0 : 255.0; }

// The mean level of a frame, as a fraction of full scale.
double ExposureLevel(const cv::Mat& image) { return cv::mean(image)[0] / FullScale(image); }

double MatchExposure(cv::Mat* image, double reference_level) {
  if (image->empty() || !(reference_level > 0)) return 1;
  const double level = ExposureLevel(*image);
  if (!(level > 0)) return 1;
  const double gain = reference_level / level;
  if (std::abs(gain - 1) <= 0.03) return 1;
  cv::Mat scaled;
  image->convertTo(scaled, CV_16U, gain * 65535.0 / FullScale(*image));
  *image = scaled;
  return gain;
}

// The named dots drawn on a fisheye frame (--overlay).
cv::Mat DrawNamed(const cv::Mat& grey, const CameraFrameTracks& tracks,
                  const MarkerLayout& layout, const std::string& label) {
  cv::Mat bgr;
  cv::cvtColor(ToGrey8(grey), bgr, cv::COLOR_GRAY2BGR);
  for (size_t i = 0; i < tracks.marker.size(); ++i) {
    DrawNamedDot(&bgr, tracks.pixel[i], layout.names[tracks.marker[i]]);
  }
  cv::putText(bgr, label, cv::Point(8, 22), cv::FONT_HERSHEY_SIMPLEX, 0.6,
              cv::Scalar(255, 255, 255), 1, cv::LINE_AA);
  return bgr;
}

// A proxy's crop: the box of the reference frame's named dots with a margin
// of 35 % of its size (the head moves in the helmet, the jaw opens) and 10
// px, inside the image.
cv::Rect ProxyCrop(const CameraFrameTracks& tracks, cv::Size size) {
  const cv::Rect whole(0, 0, size.width, size.height);
  if (tracks.pixel.empty()) return whole;
  double x0 = 1e30, y0 = 1e30, x1 = -1e30, y1 = -1e30;
  for (const Vec2& p : tracks.pixel) {
    x0 = std::min(x0, p.x());
    y0 = std::min(y0, p.y());
    x1 = std::max(x1, p.x());
    y1 = std::max(y1, p.y());
  }
  const double margin = 0.35 * std::max(x1 - x0, y1 - y0) + 10;
  const cv::Rect box(cv::Point(static_cast<int>(x0 - margin), static_cast<int>(y0 - margin)),
                     cv::Point(static_cast<int>(x1 + margin), static_cast<int>(y1 + margin)));
  const cv::Rect clipped = box & whole;
  return clipped.area() > 0 ? clipped : whole;
}

// The proxy JPEG of one view: the frame as the tracker saw it (linear
// light, exposure matched), encoded back to sRGB for a camera read as sRGB
// so that it looks as stored.
std::string ProxyJpeg(const cv::Mat& image, bool srgb, cv::Rect crop, int height, int quality) {
  cv::Mat grey;
  if (srgb) {
    static const std::vector<uint8_t> lut = [] {
      std::vector<uint8_t> t(65536);
      for (int i = 0; i < 65536; ++i) {
        const double v = i / 65535.0;
        const double e = v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1 / 2.4) - 0.055;
        t[i] = static_cast<uint8_t>(std::lround(255 * std::clamp(e, 0.0, 1.0)));
      }
      return t;
    }();
    cv::Mat wide;
    image(crop).convertTo(wide, CV_16U, image.depth() == CV_16U ? 1.0 : 257.0);
    grey.create(wide.size(), CV_8U);
    for (int y = 0; y < wide.rows; ++y) {
      const uint16_t* in = wide.ptr<uint16_t>(y);
      uint8_t* out = grey.ptr<uint8_t>(y);
      for (int x = 0; x < wide.cols; ++x) out[x] = lut[in[x]];
    }
  } else {
    grey = ToGrey8(image(crop));
  }
  const double s = static_cast<double>(height) / grey.rows;
  cv::Mat small;
  cv::resize(grey, small, cv::Size(), s, s, s < 1 ? cv::INTER_AREA : cv::INTER_LINEAR);
  std::vector<uchar> jpeg;
  cv::imencode(".jpg", small, jpeg, {cv::IMWRITE_JPEG_QUALITY, quality});
  return std::string(jpeg.begin(), jpeg.end());
}

nlohmann::json CameraJson(const CameraFrameTracks& t, const std::string& error,
                          const MarkerLayout& layout) {
  nlohmann::json j;
  j["detections"] = t.detections;
  j["named"] = t.marker.size();
  j["unnamed"] = t.unnamed;
  j["lost"] = t.lost;
  j["reacquired"] = t.reacquired;
  j["swaps_caught"] = t.swaps_caught;
  j["searched"] = t.searched;
  j["lost_dropped"] = t.lost_dropped;
  j["skipped"] = t.skipped;
  nlohmann::json vacant = nlohmann::json::array();
  for (int k : t.vacant) vacant.push_back(layout.names[k]);
  j["vacant"] = vacant;
  if (!error.empty()) j["error"] = error;
  return j;
}

// Follows the tracker's lost dots after each frame (MarkerTracker::
// lost_since): a marker newly lost opens an episode from the first frame
// it was missing (it has no rows since: missing means named in no
// camera); a marker named in both cameras again closes it at this frame.
void TrackLostDots(const std::vector<int>& lost_since, const std::vector<int>& frame_of,
                   const MarkerLayout& layout, std::vector<int>* episode,
                   std::vector<TrackSummary::LostDot>* lost) {
  for (size_t k = 0; k < lost_since.size(); ++k) {
    int& open = (*episode)[k];
    if (lost_since[k] < 0) {
      if (open >= 0) (*lost)[open].back_frame = frame_of.back();
      open = -1;
    } else if (open < 0) {
      open = static_cast<int>(lost->size());
      lost->push_back({layout.names[k], frame_of[lost_since[k]], 0});
    }
  }
}

}  // namespace

TrackOutput RunTrack(const TrackInput& input, const TrackOptions& options) {
  if (!options.Check()) throw InputError("invalid track options (see the message above)");
  const auto start = std::chrono::steady_clock::now();
  ThreadLimit thread_limit(options.threads);
  const HelmetRig rig = ReadCalibration(input.calibration);
  if (rig.cameras.size() != 2) {
    ThrowInputError(input.calibration, 0, "hmc track needs two cameras, the file has {}",
                    rig.cameras.size());
  }
  const Actor actor = *LoadActorForDay(input.actor, options.day.markers);
  if (actor.markers.size() < 3) {
    ThrowInputError(input.actor, 0, "the actor has {} markers; tracking needs at least 3",
                    actor.markers.size());
  }
  const MarkerLayout layout = MakeMarkerLayout(actor, options.tracker.neighbours);
  const std::vector<std::string> names = rig.CameraNames();
  std::vector<cv::Size> sizes;
  for (const HelmetCamera& hc : rig.cameras) sizes.emplace_back(hc.camera.width, hc.camera.height);
  // The fixes, per frame and camera, resolved to the layout's markers.
  std::vector<TrackFix> fixes;
  std::map<int, std::vector<std::vector<TrackerFix>>> fixes_at;
  std::map<int, std::vector<std::vector<int>>> fix_lines;  // the same, their lines in the file
  if (!input.fixes.empty()) {
    fixes = ReadTrackFixesCsv(input.fixes, names, layout.names);
    std::map<std::string, int> marker_of, camera_of;
    for (size_t k = 0; k < layout.names.size(); ++k) marker_of[layout.names[k]] = static_cast<int>(k);
    for (size_t c = 0; c < names.size(); ++c) camera_of[names[c]] = static_cast<int>(c);
    for (const TrackFix& f : fixes) {
      TrackerFix t;
      t.action = f.action;
      t.marker = f.marker.empty() ? -1 : marker_of.at(f.marker);
      t.to = f.to.empty() ? -1 : marker_of.at(f.to);
      t.has_pixel = f.has_pixel;
      t.pixel = f.pixel;
      auto& at = fixes_at[f.frame];
      auto& lines = fix_lines[f.frame];
      at.resize(names.size());
      lines.resize(names.size());
      at[camera_of.at(f.camera)].push_back(t);
      lines[camera_of.at(f.camera)].push_back(f.line);
    }
  }
  TrackOutput output;
  FootageReader reader(input.shot, names, options.footage, sizes);
  const int num_cameras = reader.num_cameras();
  // The detector measures light: sRGB footage is linearised before it
  // (docs/tracking.md, "Images"); which encoding each camera was read as
  // is logged and goes to summary.json.
  TrackSummary& summary = output.summary;
  for (int c = 0; c < num_cameras; ++c) {
    summary.transfer.push_back(reader.transfer(c));
    summary.transfer_why.push_back(reader.transfer_why(c));
    spdlog::info("track: {} read as {} ({})", names[c], reader.transfer(c), reader.transfer_why(c));
  }
  if (!input.overlay_dir.empty()) EnsureDirectory(input.overlay_dir);
  if (!input.out.parent_path().empty()) EnsureDirectory(input.out.parent_path());

  MarkerTracker tracker(rig, layout, options.tracker, options.detect);
  nlohmann::json frames_json = nlohmann::json::array();
  std::vector<double> dot_size(num_cameras, options.detect.dot_size_px);
  std::vector<double> reference_level(num_cameras, 0);  // mean linear level, per camera
  bool started = false;
  int64_t detections_total = 0, named_total = 0, views = 0;
  // Per marker: the frames where its dot was missing in some camera
  // (CameraFrameTracks::vacant), and the last such frame.
  std::vector<int> vacant_frames(layout.names.size(), 0);
  std::vector<int> vacant_in(layout.names.size(), std::numeric_limits<int>::min());
  // What the frame's fixes did (a camera whose image was missing applied none).
  std::set<int> fixed_frames;
  auto count_fixes = [&](int frame, const std::vector<FixOutcome>& outcome) {
    const auto lines = fix_lines.find(frame);
    if (lines == fix_lines.end()) return;
    fixed_frames.insert(frame);
    for (size_t c = 0; c < lines->second.size(); ++c) {
      if (c >= outcome.size()) {
        for (int line : lines->second[c]) summary.fixes_unmatched_lines.push_back(line);
        continue;
      }
      summary.fixes_applied += outcome[c].applied;
      for (int i : outcome[c].unmatched) summary.fixes_unmatched_lines.push_back(lines->second[c][i]);
    }
  };
  // Dots lost mid-take: the frame of each tracker frame (0: the reference
  // frame), each marker's open episode (index into summary.lost_dots, -1).
  std::vector<int> frame_of;
  std::vector<int> lost_episode(layout.names.size(), -1);
  std::vector<cv::Rect> proxy_crops;          // per camera (input.proxy_dir)
  std::vector<std::vector<int>> proxy_frames;  // per camera: the frames with a proxy
  Progress progress("track", reader.num_frames());
  // Decoding of frame n + 1 runs beside the detection of frame n.
  FootageReadAhead frames(&reader, true);
  while (std::unique_ptr<FootageFrame> frame = frames.Next()) {
    progress.Advance();
    if (frame->frame < options.reference_frame) continue;
    std::vector<bool> present(num_cameras);
    for (int c = 0; c < num_cameras; ++c) present[c] = !frame->images[c].empty();
    if (!started) {
      if (!frame->complete()) {
        summary.warnings.push_back(fmt::format(
            "reference frame {} is incomplete; labelling at the next complete frame",
            frame->frame));
        continue;
      }
      for (int c = 0; c < num_cameras; ++c) {
        if (dot_size[c] > 0) continue;
        dot_size[c] = MeasureDotSize(frame->images[c], options.detect);
        if (dot_size[c] <= 0) {
          ThrowInputError(reader.source(c), 0,
                          "no painted dots found at the reference frame {} (set --detect.dot_size_px "
                          "or check --detect.polarity)",
                          frame->frame);
        }
      }
    }
    if (!started) {
      for (int c = 0; c < num_cameras; ++c) reference_level[c] = ExposureLevel(frame->images[c]);
    } else {
      for (int c = 0; c < num_cameras; ++c) {
        const double gain = MatchExposure(&frame->images[c], reference_level[c]);
        if (gain != 1) ++summary.exposure_matched_views;
      }
    }
    std::vector<std::vector<DotDetection>> detections(num_cameras);
    ParallelFor(0, num_cameras, [&](int64_t c) {
      if (present[c]) detections[c] = DetectDots(frame->images[c], options.detect, dot_size[c]);
    });
    std::vector<CameraFrameTracks> result;
    if (!started) {
      for (int c = 0; c < num_cameras; ++c) {
        spdlog::debug("reference frame {} {}: dot size {:.2f} px, {} detections", frame->frame,
                      names[c], dot_size[c], detections[c].size());
      }
      const auto fix = fixes_at.find(frame->frame);
      std::vector<FixOutcome> outcome;
      result = tracker.Start(detections, frame->images, dot_size,
                             fix == fixes_at.end() ? nullptr : &fix->second, &outcome);
      count_fixes(frame->frame, outcome);
      summary.labelling = tracker.labelling();
      if (!summary.labelling.ok) {
        ThrowInputError(input.shot, 0, "cannot label the reference frame {}: {}", frame->frame,
                        summary.labelling.reason);
      }
      summary.reference_frame = frame->frame;
      started = true;
    } else {
      const auto fix = fixes_at.find(frame->frame);
      std::vector<FixOutcome> outcome;
      result = tracker.Step(detections, frame->images,
                            fix == fixes_at.end() ? nullptr : &fix->second, &outcome);
      count_fixes(frame->frame, outcome);
    }
    if (!input.proxy_dir.empty()) {
      if (proxy_crops.empty()) {
        for (int c = 0; c < num_cameras; ++c) {
          proxy_crops.push_back(ProxyCrop(result[c], frame->images[c].size()));
          EnsureDirectory(input.proxy_dir / names[c]);
        }
        proxy_frames.assign(num_cameras, {});
      }
      ParallelFor(0, num_cameras, [&](int64_t c) {
        if (!present[c]) return;
        WriteFileAtomic(input.proxy_dir / names[c] / fmt::format("{:06d}.jpg", frame->frame),
                        ProxyJpeg(frame->images[c], summary.transfer[c] == "srgb", proxy_crops[c],
                                  input.proxy_height, input.proxy_quality));
        proxy_frames[c].push_back(frame->frame);
      });
    }
    ++summary.frames;
    nlohmann::json frame_json;
    frame_json["frame"] = frame->frame;
    for (int c = 0; c < num_cameras; ++c) {
      const CameraFrameTracks& t = result[c];
      if (t.skipped) ++summary.skipped_views;
      if (!t.skipped) {
        ++views;
        detections_total += t.detections;
        named_total += static_cast<int64_t>(t.marker.size());
      }
      summary.reacquired += t.reacquired;
      summary.swaps_caught += t.swaps_caught;
      for (int k : t.vacant) vacant_in[k] = frame->frame;
      for (size_t i = 0; i < t.marker.size(); ++i) {
        Track2d row;
        row.frame = frame->frame;
        row.camera = names[c];
        row.marker = layout.names[t.marker[i]];
        row.pixel = t.pixel[i];
        row.score = t.score[i];
        output.tracks.push_back(row);
      }
      frame_json["cameras"][names[c]] = CameraJson(t, frame->errors[c], layout);
      if (!input.overlay_dir.empty() && present[c]) {
        WritePng(input.overlay_dir / fmt::format("frame_{:06d}_{}.png", frame->frame, names[c]),
                 DrawNamed(frame->images[c], t, layout,
                           fmt::format("frame {} {}: {} named", frame->frame, names[c],
                                       t.marker.size())));
      }
    }
    frames_json.push_back(frame_json);
    for (size_t m = 0; m < vacant_in.size(); ++m) vacant_frames[m] += vacant_in[m] == frame->frame;
    frame_of.push_back(frame->frame);
    TrackLostDots(tracker.lost_since(), frame_of, layout, &lost_episode, &summary.lost_dots);
  }
  progress.Finish();
  if (!started) {
    ThrowInputError(input.shot, 0, "no complete frame at or after the reference frame {}",
                    options.reference_frame);
  }
  for (const std::string& w : reader.warnings()) summary.warnings.push_back(w);
  summary.fixes = static_cast<int>(fixes.size());
  for (const auto& [frame, lines] : fix_lines) {
    if (fixed_frames.count(frame)) continue;  // a frame not tracked (before the reference, outside the range)
    for (const auto& camera_lines : lines) {
      for (int line : camera_lines) summary.fixes_unmatched_lines.push_back(line);
    }
  }
  std::sort(summary.fixes_unmatched_lines.begin(), summary.fixes_unmatched_lines.end());
  if (!summary.fixes_unmatched_lines.empty()) {
    summary.warnings.push_back(fmt::format(
        "{} of the {} fixes of {} not applied (no dot where they point, or a frame not tracked): "
        "lines {}",
        summary.fixes_unmatched_lines.size(), fixes.size(), input.fixes.string(),
        fmt::join(summary.fixes_unmatched_lines, ", ")));
  }
  std::vector<bool> found(layout.names.size(), false);
  std::map<std::string, size_t> index;
  for (size_t m = 0; m < layout.names.size(); ++m) index[layout.names[m]] = m;
  for (const Track2d& row : output.tracks) found[index.at(row.marker)] = true;
  // A marker hidden all along, or seen only at a grazing angle, is never
  // found in a clean shot too: only the never-found markers whose dot was
  // missing where it should have been seen are warned.
  for (size_t m = 0; m < found.size(); ++m) {
    if (found[m]) continue;
    summary.never_found.push_back(layout.names[m]);
    if (2 * vacant_frames[m] >= summary.frames) summary.missing_dots.push_back(layout.names[m]);
  }
  if (!summary.missing_dots.empty()) {
    const std::vector<std::string>& missing = summary.missing_dots;
    const size_t shown = std::min<size_t>(missing.size(), 12);
    summary.warnings.push_back(fmt::format(
        "{} of the actor's {} markers never found over the shot, their dots missing where "
        "they face a camera ({}{}): not painted, or painted elsewhere -- if painted elsewhere, "
        "the names of the dots near them may be wrong",
        missing.size(), layout.names.size(),
        fmt::join(missing.begin(), missing.begin() + shown, ", "),
        missing.size() > shown ? ", ..." : ""));
  }
  std::vector<std::string> lost_to_end;
  for (const TrackSummary::LostDot& l : summary.lost_dots) {
    if (l.back_frame == 0) lost_to_end.push_back(fmt::format("{} from frame {}", l.marker, l.from_frame));
  }
  if (!lost_to_end.empty()) {
    summary.warnings.push_back(fmt::format(
        "{} dots lost mid-take (missing where they should be seen, not named from then on): {}",
        lost_to_end.size(), fmt::join(lost_to_end, ", ")));
  }
  for (const std::string& w : summary.warnings) spdlog::warn("track: {}", w);
  summary.dot_size_px = dot_size;
  summary.mean_detections = views ? static_cast<double>(detections_total) / views : 0;
  summary.mean_named = views ? static_cast<double>(named_total) / views : 0;
  summary.rows = static_cast<int64_t>(output.tracks.size());

  if (!input.proxy_dir.empty()) {
    nlohmann::json proxies = {{"height", input.proxy_height},
                              {"quality", input.proxy_quality},
                              {"cameras", nlohmann::json::array()}};
    for (int c = 0; c < num_cameras && c < static_cast<int>(proxy_crops.size()); ++c) {
      const cv::Rect& r = proxy_crops[c];
      proxies["cameras"].push_back({{"name", names[c]},
                                    {"width", sizes[c].width},
                                    {"height", sizes[c].height},
                                    {"crop", {r.x, r.y, r.width, r.height}},
                                    {"frames", proxy_frames[c]}});
    }
    WriteFileAtomic(input.proxy_dir / "proxies.json", proxies.dump() + "\n");
  }
  WriteTracks2dCsv(input.out, output.tracks);
  // The fixes used are kept beside the tracks (the workspace records them).
  if (!input.fixes.empty()) {
    WriteFileAtomic(input.out.parent_path() / "track_fixes_used.csv", TrackFixesCsvText(fixes));
  }
  OptionFields used;
  TrackOptions copy = options;
  copy.Register(&used);
  WriteOptionsUsed(used, input.out.parent_path() / "options_used.yaml", "track");
  summary.seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  nlohmann::json j;
  j["stage"] = "track";
  j["reference_frame"] = summary.reference_frame;
  j["dot_size_px"] = summary.dot_size_px;
  for (int c = 0; c < num_cameras; ++c) {
    j["transfer"][names[c]] = {{"read_as", summary.transfer[c]}, {"why", summary.transfer_why[c]}};
  }
  j["labelling"] = {{"ok", summary.labelling.ok},
                    {"candidate_points", summary.labelling.candidate_points},
                    {"paired_share", summary.labelling.paired_share},
                    {"median_gap_mm", summary.labelling.median_gap_mm},
                    {"rigid_inliers", summary.labelling.rigid_inliers},
                    {"expression_inliers", summary.labelling.expression_inliers},
                    {"expression", summary.labelling.expression},
                    {"inliers", summary.labelling.inliers},
                    {"rms_mm", summary.labelling.rms_mm},
                    {"jaw",
                     {{"open_deg", summary.labelling.jaw.open_deg},
                      {"lateral_deg", summary.labelling.jaw.lateral_deg},
                      {"protrude_mm", summary.labelling.jaw.protrude_mm}}}};
  j["warnings"] = summary.warnings;  // with every frame that failed to decode
  if (!input.fixes.empty()) {
    j["fixes"] = {{"file", input.fixes.string()},
                  {"rows", summary.fixes},
                  {"applied", summary.fixes_applied},
                  {"unmatched_lines", summary.fixes_unmatched_lines}};
  }
  j["never_found"] = summary.never_found;
  j["missing_dots"] = summary.missing_dots;
  j["lost_dots"] = nlohmann::json::array();
  for (const TrackSummary::LostDot& l : summary.lost_dots) {
    j["lost_dots"].push_back({{"marker", l.marker},
                              {"from_frame", l.from_frame},
                              {"back_frame", l.back_frame > 0 ? nlohmann::json(l.back_frame)
                                                              : nlohmann::json()}});
  }
  j["summary"] = {{"frames", summary.frames},
                  {"skipped_views", summary.skipped_views},
                  {"mean_detections", summary.mean_detections},
                  {"mean_named", summary.mean_named},
                  {"reacquired", summary.reacquired},
                  {"swaps_caught", summary.swaps_caught},
                  {"exposure_matched_views", summary.exposure_matched_views},
                  {"rows", summary.rows},
                  {"seconds", summary.seconds}};
  if (!input.diagnostics.empty()) {
    nlohmann::json d = j;
    d["frames"] = frames_json;
    WriteFileAtomic(input.diagnostics, d.dump(1));
  }
  WriteFileAtomic(input.out.parent_path() / "summary.json", j.dump(1) + "\n");  // last
  return output;
}

}  // namespace hmc
