#include "pipeline/review.h"

#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstring>
#include <cmath>
#include <cstdlib>
#include <future>
#include <map>
#include <set>
#include <system_error>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <spdlog/spdlog.h>
#include <yaml-cpp/yaml.h>
#include <zlib.h>

#include "core/calibration.h"
#include "core/error.h"
#include "core/file_util.h"
#include "core/frame_data.h"
#include "core/mesh_sequence.h"
#include "core/obj_io.h"
#include "core/parallel.h"
#include "core/text.h"
#include "core/tracks_2d.h"
#include "pipeline/report.h"
#include "pipeline/run_pipeline.h"
#include "tracking/footage_reader.h"

namespace hmc {

namespace fs = std::filesystem;

void ReviewOptions::Register(OptionFields* fields) {
  fields->Add("proxy_height", &proxy_height, "height of the footage proxies (px)").In(64, 2160);
  fields->Add("jpeg_quality", &jpeg_quality, "JPEG quality of the proxies (1-100)").In(1, 100);
  fields->Add("chunk_frames", &chunk_frames, "frames per data chunk the page loads at a time")
      .In(1, 256);
  fields->Add("error_max_mm", &error_max_mm, "top of the error-against-truth colour scale (mm)")
      .Above(0)
      .AtMost(100);
  fields->Add("residual_max_mm", &residual_max_mm, "top of the bundle-residual colour scale (mm)")
      .Above(0)
      .AtMost(100);
}

bool ReviewOptions::Check() const {
  CHECK_OPTION_LIMITS();
  return true;
}

std::string ReviewSummary::BriefReport() const {
  return fmt::format(
      "{} frames, {} cameras, {} proxies ({:.1f} MB, {:.1f} % of the footage's {:.1f} MB), data "
      "{:.1f} MB, {}{} in {:.2f} s",
      frames, cameras, proxies, proxy_bytes / 1e6,
      footage_bytes > 0 ? 100.0 * proxy_bytes / footage_bytes : 0.0, footage_bytes / 1e6,
      data_bytes / 1e6, has_mesh ? "mesh" : "no mesh", has_truth ? " with its error against the truth" : "",
      seconds);
}

fs::path ReviewAssetsDir() {
  fs::path dir;
  if (const char* env = std::getenv("HMC_REVIEW_ASSETS"); env && *env) {
    dir = env;
  } else {
    std::error_code ec;
    const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
    dir = exe.parent_path().parent_path() / "share" / "hmc" / "review";
  }
  for (const char* f : {"index.html", "review.js", "review.css", "three.min.js", "OrbitControls.js"}) {
    if (!fs::is_regular_file(dir / f)) {
      ThrowInputError(dir / f, 0,
                      "the review page's files are missing (built from pipeline/review_page and "
                      "Debian's libjs-three; set HMC_REVIEW_ASSETS to their folder)");
    }
  }
  return dir;
}

namespace {

enum DotState { kNamed = 0, kFlagged = 1, kInterpolated = 2, kRejected = 3 };

bool IsFile(const fs::path& p) {
  std::error_code ec;
  return fs::is_regular_file(p, ec);
}

nlohmann::json ReadJson(const fs::path& file) {
  try {
    return nlohmann::json::parse(ReadFile(file));
  } catch (const nlohmann::json::exception& e) {
    ThrowInputError(file, 0, "not JSON: {}", e.what());
  }
}

int64_t PathBytes(const fs::path& p) {
  std::error_code ec;
  if (fs::is_regular_file(p, ec)) return static_cast<int64_t>(fs::file_size(p, ec));
  int64_t total = 0;
  if (fs::is_directory(p, ec)) {
    for (const auto& e : fs::recursive_directory_iterator(p, ec)) {
      if (e.is_regular_file(ec)) total += static_cast<int64_t>(e.file_size(ec));
    }
  }
  return total;
}

// Where the run's shot is: the `run_inputs` a stage summary of hmc run
// records (pipeline/run_pipeline.cc).
fs::path RecordedShot(const fs::path& work) {
  for (const std::string& stage : PipelineStages()) {
    const fs::path file = work / stage / "summary.json";
    if (!IsFile(file)) continue;
    const nlohmann::json s = ReadJson(file);
    const nlohmann::json report = s.value("report", nlohmann::json::object());
    if (report.contains("run_inputs")) return report["run_inputs"].value("shot", std::string());
  }
  return {};
}

// The footage as the run's track stage read it: its cameras, frame range
// and offset (WORK/track/options_used.yaml).
FootageOptions TrackFootage(const fs::path& work) {
  FootageOptions footage;
  const fs::path used = work / "track" / "options_used.yaml";
  if (!IsFile(used)) return footage;
  const YAML::Node n = LoadYamlFile(used);
  if (n["cam0"]) footage.cam0 = n["cam0"].as<std::string>();
  if (n["cam1"]) footage.cam1 = n["cam1"].as<std::string>();
  if (n["frames"]) footage.frames = n["frames"].as<std::string>();
  if (n["offset1"]) footage.offset1 = n["offset1"].as<int>();
  return footage;
}

std::string Num(double v, int decimals) {
  if (!std::isfinite(v)) return "null";
  return fmt::format("{:.{}f}", v, decimals);
}

class ReviewWriter {
 public:
  ReviewWriter(const ReviewInput& input, const ReviewOptions& options, const fs::path& out)
      : in_(input), options_(options), work_(input.work), out_(out) {}
  ReviewSummary Write();

 private:
  fs::path Stage(const std::string& stage, const std::string& file) const { return work_ / stage / file; }
  int MarkerIndex(const std::string& name) {
    const auto it = marker_index_.find(name);
    if (it != marker_index_.end()) return it->second;
    marker_index_[name] = static_cast<int>(markers_.size());
    markers_.push_back(name);
    return static_cast<int>(markers_.size()) - 1;
  }
  void ReadTracks();
  void ReadStates();
  void ReadBundles();
  // Per camera and frame a proxy JPEG (out/footage/<camera>/), its crop.
  void WriteProxies();
  // The track stage's proxies (WORK/track/proxies/), copied; false if it
  // made none.
  bool CopyTrackProxies();
  void WriteTopology();
  void WriteChunks();
  void WriteMeta();
  void WriteScript(const fs::path& rel, const std::string& text) {
    WriteFileAtomic(out_ / rel, text);
    summary_.data_bytes += static_cast<int64_t>(text.size());
  }

  ReviewInput in_;
  ReviewOptions options_;
  fs::path work_, out_, shot_;
  ReviewSummary summary_;
  std::vector<std::string> cameras_;
  std::vector<cv::Size> sizes_;
  std::vector<cv::Rect> crops_;
  std::vector<std::vector<int>> proxy_frames_;  // per camera
  std::vector<std::string> markers_;
  std::map<std::string, int> marker_index_;
  int first_ = INT32_MAX, last_ = INT32_MIN;    // the cursor's frames
  int footage_first_ = INT32_MAX, footage_last_ = INT32_MIN;
  double fps_ = 30;
  std::vector<Track2d> tracks_;
  std::map<std::pair<int, int>, int> state_;  // (frame, marker) -> DotState above kNamed
  std::set<int> interpolated_;                // frames
  // frame -> per bundle: marker, x, y, z (head space), residual (mm), outside (0/1)
  std::map<int, std::vector<std::array<double, 6>>> bundles_;
  nlohmann::json report_data_;  // WORK/report/plots.json
  TriMesh neutral_;
  bool has_mesh_ = false;
  int mesh_start_ = 0, mesh_frames_ = 0;
};

void ReviewWriter::ReadTracks() {
  const fs::path file = Stage("track", "tracks_2d.csv");
  if (!IsFile(file)) ThrowInputError(file, 0, "the workspace has no tracks: run hmc run first");
  tracks_ = ReadTracks2dCsv(file);
  for (const Track2d& t : tracks_) {
    MarkerIndex(t.marker);
    first_ = std::min(first_, t.frame);
    last_ = std::max(last_, t.frame);
  }
  // Markers never found are still names a fix may give.
  const fs::path track_summary = Stage("track", "summary.json");
  if (IsFile(track_summary)) {
    const nlohmann::json s = ReadJson(track_summary);
    for (const auto& m : s.value("never_found", nlohmann::json::array())) {
      if (m.is_string()) MarkerIndex(m.get<std::string>());
    }
  }
}

// The dots' states beyond "named", from the report's warnings (which name
// markers and frames): flagged by stabilize (a bad track, at the frames its
// residual is over the threshold), rejected by the triangulation (its
// dropped marker-frames); and interpolated (stabilize could not fit the
// frame).
void ReviewWriter::ReadStates() {
  const fs::path plots = Stage("report", "plots.json");
  if (IsFile(plots)) report_data_ = ReadJson(plots);
  for (const auto& w : report_data_.value("warnings", nlohmann::json::array())) {
    const std::string stage = w.value("stage", std::string());
    if (stage != "stabilize" && stage != "triangulate") continue;
    const int state = stage == "stabilize" ? kFlagged : kRejected;
    for (const auto& m : w.value("markers", nlohmann::json::array())) {
      const int k = MarkerIndex(m.get<std::string>());
      for (const auto& f : w.value("frames", nlohmann::json::array())) {
        int& s = state_[{f.get<int>(), k}];
        s = std::max(s, state);  // rejected over flagged
      }
    }
  }
  const fs::path stabilize = Stage("stabilize", "summary.json");
  if (IsFile(stabilize)) {
    const nlohmann::json s = ReadJson(stabilize);
    const nlohmann::json cs =
        s.value("report", nlohmann::json::object()).value("command_summary", nlohmann::json::object());
    for (const auto& f : cs.value("interpolated_frames", nlohmann::json::array())) {
      interpolated_.insert(f.value("frame", 0));
    }
  }
}

void ReviewWriter::ReadBundles() {
  const fs::path file = Stage("stabilize", "bundles.csv");
  if (!IsFile(file)) return;
  // Per (frame, marker): the solve's residual and whether it fell outside
  // its data (diagnostics.json, streamed).
  std::map<std::pair<int, int>, std::pair<double, bool>> solve;
  const fs::path diag = Stage("solve", "diagnostics.json");
  if (IsFile(diag)) {
    ForEachSolveFrame(diag, [&](const nlohmann::json& f) {
      const int frame = f.value("frame", 0);
      for (const auto& b : f["bundles"]) {
        const std::string status = b.value("status", std::string());
        if (status == "filled") continue;
        solve[{frame, MarkerIndex(b.value("marker", std::string()))}] = {b.value("residual_mm", 0.0),
                                                                          status == "projected"};
      }
    });
  }
  for (const BundleFrame& f : ReadBundlesCsv(file)) {
    auto& list = bundles_[f.frame];
    for (const auto& [marker, p] : f.bundles) {
      const int k = MarkerIndex(marker);
      const auto s = solve.find({f.frame, k});
      list.push_back({double(k), p.x(), p.y(), p.z(), s == solve.end() ? std::nan("") : s->second.first,
                      s != solve.end() && s->second.second ? 1.0 : 0.0});
    }
  }
}

bool ReviewWriter::CopyTrackProxies() {
  const fs::path dir = Stage("track", "proxies");
  if (!IsFile(dir / "proxies.json")) return false;
  const nlohmann::json p = ReadJson(dir / "proxies.json");
  std::map<std::string, nlohmann::json> by_name;
  for (const auto& c : p.value("cameras", nlohmann::json::array())) by_name[c.value("name", "")] = c;
  for (const std::string& name : cameras_) {
    if (!by_name.count(name)) return false;  // not this calibration's cameras: decode the footage
  }
  proxy_frames_.assign(cameras_.size(), {});
  for (size_t c = 0; c < cameras_.size(); ++c) {
    const nlohmann::json& cam = by_name[cameras_[c]];
    const auto crop = cam.value("crop", std::vector<int>{});
    if (crop.size() != 4) ThrowInputError(dir / "proxies.json", 0, "camera {}: crop is not x, y, width, height", cameras_[c]);
    crops_.emplace_back(crop[0], crop[1], crop[2], crop[3]);
    EnsureDirectory(out_ / "footage" / cameras_[c]);
    for (const int f : cam.value("frames", std::vector<int>{})) {
      const std::string file = fmt::format("{:06d}.jpg", f);
      // Hard-linked, not copied: no data written (a track stage redone
      // later replaces its files, this page keeps its own); a copy where
      // the file system refuses links. The folder is written whole
      // (WriteFolderAtomic), so no proxy is ever seen half-written.
      const fs::path from = dir / cameras_[c] / file, to = out_ / "footage" / cameras_[c] / file;
      std::error_code ec;
      fs::create_hard_link(from, to, ec);
      if (ec) WriteFileAtomic(to, ReadFile(from));
      summary_.proxy_bytes += static_cast<int64_t>(fs::file_size(to));
      ++summary_.proxies;
      proxy_frames_[c].push_back(f);
      footage_first_ = std::min(footage_first_, f);
      footage_last_ = std::max(footage_last_, f);
    }
  }
  return true;
}

void ReviewWriter::WriteProxies() {
  FootageReader reader(shot_, cameras_, TrackFootage(work_));
  if (reader.fps() > 0) fps_ = reader.fps();
  for (int c = 0; c < reader.num_cameras(); ++c) summary_.footage_bytes += PathBytes(reader.source(c));
  // The track stage's proxies when it made them (hmc run does): the
  // footage is not decoded a second time.
  if (CopyTrackProxies()) return;
  footage_first_ = reader.first_frame();
  footage_last_ = reader.last_frame();
  const int n = reader.num_cameras();
  proxy_frames_.assign(n, {});
  for (int c = 0; c < n; ++c) {
    EnsureDirectory(out_ / "footage" / cameras_[c]);
    // The proxy shows the face: the box of the camera's named dots over
    // the shot, as the report's contact sheet frames it.
    crops_.push_back(NamedDotsBox(tracks_, cameras_[c], reader.image_size(c)));
  }
  const std::vector<int> params = {cv::IMWRITE_JPEG_QUALITY, options_.jpeg_quality};
  std::vector<int64_t> bytes(n, 0);
  // Decoding the next frame runs beside the encoding of this one.
  FootageReadAhead frames(&reader, false);
  while (std::unique_ptr<FootageFrame> frame = frames.Next()) {
    ParallelFor(0, n, [&](int64_t camera) {
      const int c = static_cast<int>(camera);
      if (frame->images[c].empty()) return;
      cv::Mat grey = ToGrey8(frame->images[c])(crops_[c]);
      const double s = static_cast<double>(options_.proxy_height) / grey.rows;
      cv::Mat small;
      cv::resize(grey, small, cv::Size(), s, s, s < 1 ? cv::INTER_AREA : cv::INTER_LINEAR);
      std::vector<uchar> jpeg;
      cv::imencode(".jpg", small, jpeg, params);
      WriteFileAtomic(out_ / "footage" / cameras_[c] / fmt::format("{:06d}.jpg", frame->frame),
                      std::string(jpeg.begin(), jpeg.end()));
      bytes[c] += static_cast<int64_t>(jpeg.size());
    });
    for (int c = 0; c < n; ++c) {
      if (!frame->images[c].empty()) proxy_frames_[c].push_back(frame->frame);
    }
  }
  for (int c = 0; c < n; ++c) {
    summary_.proxy_bytes += bytes[c];
    summary_.proxies += static_cast<int>(proxy_frames_[c].size());
  }
}

// The neutral (float32), its triangles (uint32) and per vertex the marker
// of the nearest bundle (uint16, on the first mesh frame with bundles), for
// the colour by bundle residual.
void ReviewWriter::WriteTopology() {
  const fs::path obj = Stage("solve", "neutral.obj");
  const fs::path pc2 = Stage("solve", "mesh.pc2");
  if (!IsFile(obj) || !IsFile(pc2)) return;
  neutral_ = ReadObj(obj);
  MeshSequenceReadOptions read;
  read.topology = &neutral_;
  read.wanted = [](int) { return false; };
  const MeshSequence frames = ReadMeshSequence(pc2, read);
  mesh_start_ = frames.start_frame;
  mesh_frames_ = static_cast<int>(frames.frames.size());
  if (mesh_frames_ == 0) return;
  has_mesh_ = true;
  const Eigen::Index V = neutral_.V.rows();
  std::vector<float> positions(3 * V);
  for (Eigen::Index v = 0; v < V; ++v) {
    for (int d = 0; d < 3; ++d) positions[3 * v + d] = static_cast<float>(neutral_.V(v, d));
  }
  std::vector<uint32_t> triangles(3 * neutral_.F.rows());
  for (Eigen::Index f = 0; f < neutral_.F.rows(); ++f) {
    for (int d = 0; d < 3; ++d) triangles[3 * f + d] = static_cast<uint32_t>(neutral_.F(f, d));
  }
  std::vector<uint16_t> nearest(V, 0);
  // The first frame with both a mesh and bundles: each vertex's nearest bundle.
  for (const auto& [frame, list] : bundles_) {
    if (frame < mesh_start_ || frame >= mesh_start_ + mesh_frames_ || list.empty()) continue;
    read.wanted = [frame = frame](int f) { return f == frame; };
    const MeshSequence one = ReadMeshSequence(pc2, read);
    const MatX3d& P = one.frames[frame - mesh_start_];
    ParallelFor(0, V, [&](int64_t v) {
      double best = 1e300;
      for (const auto& b : list) {
        const double d = (P.row(v).transpose() - Vec3(b[1], b[2], b[3])).squaredNorm();
        if (d < best) {
          best = d;
          nearest[v] = static_cast<uint16_t>(b[0]);
        }
      }
    });
    break;
  }
  WriteScript("data/topology.js",
              fmt::format("hmcReview.topology({{neutral:\"{}\",triangles:\"{}\",nearest:\"{}\"}});\n",
                          Base64Encode(positions.data(), positions.size() * sizeof(float)),
                          Base64Encode(triangles.data(), triangles.size() * sizeof(uint32_t)),
                          Base64Encode(nearest.data(), nearest.size() * sizeof(uint16_t))));
}

// The smallest step of the mesh chunks' displacements (mm): 2 um, a
// rounding of at most 1 um (docs/formats.md, "Review page"), far below
// what the page can show, and a third of the size of the finest step.
constexpr double kMeshStepMm = 0.002;

// `data` deflated (zlib format, RFC 1950), which the page inflates with the
// browser's DecompressionStream("deflate").
std::string Deflate(const std::string& data) {
  if (data.empty()) return data;
  uLongf size = compressBound(static_cast<uLong>(data.size()));
  std::string out(size, '\0');
  if (compress2(reinterpret_cast<Bytef*>(out.data()), &size, reinterpret_cast<const Bytef*>(data.data()),
                static_cast<uLong>(data.size()), 6) != Z_OK) {
    throw std::runtime_error("review: zlib could not deflate a mesh chunk");
  }
  out.resize(size);
  return out;
}

// One script per chunk of frames: per frame its tracks and bundles as
// JSON, the meshes as one base64 binary (docs/formats.md, "Review page").
void ReviewWriter::WriteChunks() {
  const int chunk = options_.chunk_frames;
  const int num_chunks = (last_ - first_ + chunk) / chunk;
  // tracks_ is sorted by (frame, camera, marker).
  std::map<std::string, int> camera_index;
  for (size_t c = 0; c < cameras_.size(); ++c) camera_index[cameras_[c]] = static_cast<int>(c);
  size_t row = 0;
  const fs::path pc2 = Stage("solve", "mesh.pc2");
  const fs::path truth_file = shot_ / "truth.pc2";
  const bool truth = has_mesh_ && IsFile(truth_file);
  summary_.has_truth = truth;
  const Eigen::Index V = neutral_.V.rows();
  std::future<void> pending;
  for (int k = 0; k < num_chunks; ++k) {
    const int a = first_ + k * chunk, b = std::min(last_, a + chunk - 1);
    MeshSequence mesh, truth_mesh;
    if (has_mesh_) {
      MeshSequenceReadOptions read;
      read.topology = &neutral_;
      read.wanted = [a, b](int f) { return f >= a && f <= b; };
      mesh = ReadMeshSequence(pc2, read);
      if (truth) truth_mesh = ReadMeshSequence(truth_file, read);
    }
    std::string frames = "[";
    std::string binary;
    for (int f = a; f <= b; ++f) {
      std::vector<std::string> per_camera(cameras_.size());
      while (row < tracks_.size() && tracks_[row].frame < f) ++row;
      for (; row < tracks_.size() && tracks_[row].frame == f; ++row) {
        const Track2d& t = tracks_[row];
        const auto c = camera_index.find(t.camera);
        if (c == camera_index.end()) continue;
        const int m = marker_index_.at(t.marker);
        int state = interpolated_.count(f) ? kInterpolated : kNamed;
        const auto s = state_.find({f, m});
        if (s != state_.end()) state = s->second;
        std::string& out = per_camera[c->second];
        out += fmt::format("{}{},{},{},{}", out.empty() ? "" : ",", m, Num(t.pixel.x(), 3),
                           Num(t.pixel.y(), 3), state);
      }
      std::string tracks = "[";
      for (size_t c = 0; c < per_camera.size(); ++c) tracks += (c ? ",[" : "[") + per_camera[c] + "]";
      tracks += "]";
      std::string bundles;
      const auto bl = bundles_.find(f);
      if (bl != bundles_.end()) {
        for (const auto& x : bl->second) {
          bundles += fmt::format("{}{},{},{},{},{},{}", bundles.empty() ? "" : ",", int(x[0]),
                                 Num(x[1], 3), Num(x[2], 3), Num(x[3], 3), Num(x[4], 4), int(x[5]));
        }
      }
      const int mi = f - mesh_start_;
      const bool has = has_mesh_ && mi >= 0 && mi < mesh_frames_ && mesh.frames[mi].rows() == V;
      frames += fmt::format("{}{{\"frame\":{},\"has_mesh\":{},\"tracks\":{},\"bundles\":[{}]}}",
                            f == a ? "" : ",", f, has ? "true" : "false", tracks, bundles);
      if (!has) continue;
      // int16 displacements from the neutral in steps of the frame's
      // largest over 32767, at least kMeshStepMm, as two byte planes (low
      // bytes, then high: the high plane is nearly all 0 and 255, which
      // deflate packs tight).
      const MatX3d d = mesh.frames[mi] - neutral_.V;
      const double max_abs = d.cwiseAbs().maxCoeff();
      const float scale = static_cast<float>(std::max(kMeshStepMm, max_abs / 32767));
      const size_t at = binary.size();
      const size_t record = 4 + 6 * V + (truth ? V : 0);
      binary.resize(at + ((record + 3) & ~size_t(3)), '\0');
      std::memcpy(&binary[at], &scale, 4);
      auto* low = reinterpret_cast<uint8_t*>(&binary[at + 4]);
      uint8_t* high = low + 3 * V;
      for (Eigen::Index v = 0; v < V; ++v) {
        for (int c = 0; c < 3; ++c) {
          const auto q = static_cast<uint16_t>(static_cast<int16_t>(std::lround(d(v, c) / scale)));
          low[3 * v + c] = static_cast<uint8_t>(q & 0xff);
          high[3 * v + c] = static_cast<uint8_t>(q >> 8);
        }
      }
      const int ti = f - truth_mesh.start_frame;
      if (truth) {
        auto* e = reinterpret_cast<uint8_t*>(&binary[at + 4 + 6 * V]);
        const bool have = ti >= 0 && ti < static_cast<int>(truth_mesh.frames.size()) &&
                          truth_mesh.frames[ti].rows() == V;
        for (Eigen::Index v = 0; v < V; ++v) {
          const double err = have ? (mesh.frames[mi].row(v) - truth_mesh.frames[ti].row(v)).norm() : 0;
          e[v] = static_cast<uint8_t>(std::lround(255 * std::min(1.0, err / options_.error_max_mm)));
        }
      }
    }
    frames += "]";
    // Deflated and written beside the next chunk's reading (one at a
    // time: WriteScript counts the bytes).
    if (pending.valid()) pending.get();
    pending = std::async(std::launch::async, [this, k, frames = std::move(frames),
                                              binary = std::move(binary)]() {
      const std::string packed = Deflate(binary);
      WriteScript(fmt::format("data/chunk_{:05d}.js", k),
                  fmt::format("hmcReview.chunk({},{},\"{}\");\n", k, frames,
                              Base64Encode(packed.data(), packed.size())));
    });
  }
  if (pending.valid()) pending.get();
}

void ReviewWriter::WriteMeta() {
  nlohmann::json meta;
  meta["version"] = 1;
  meta["title"] = fs::absolute(work_).lexically_normal().filename().string();
  meta["work"] = fs::absolute(work_).lexically_normal().string();
  meta["first_frame"] = first_;
  meta["num_frames"] = last_ - first_ + 1;
  meta["fps"] = fps_;
  meta["chunk_frames"] = options_.chunk_frames;
  meta["chunks"] = (last_ - first_ + options_.chunk_frames) / options_.chunk_frames;
  meta["markers"] = markers_;
  meta["cameras"] = nlohmann::json::array();
  for (size_t c = 0; c < cameras_.size(); ++c) {
    const cv::Rect& r = crops_[c];
    meta["cameras"].push_back({{"name", cameras_[c]},
                               {"width", sizes_[c].width},
                               {"height", sizes_[c].height},
                               {"crop", {r.x, r.y, r.width, r.height}},
                               {"frames", proxy_frames_[c]}});
  }
  if (has_mesh_) {
    meta["mesh"] = {{"vertices", neutral_.V.rows()},
                    {"triangles", neutral_.F.rows()},
                    {"has_error", summary_.has_truth},
                    {"error_max_mm", options_.error_max_mm},
                    {"residual_max_mm", options_.residual_max_mm}};
  } else {
    meta["mesh"] = nullptr;
  }
  meta["plots"] = report_data_.value("plots", nlohmann::json::array());
  meta["warnings"] = report_data_.value("warnings", nlohmann::json::array());
  if (!IsFile(Stage("report", "plots.json"))) {
    meta["warnings"].push_back({{"stage", "review"},
                                {"text", "no report/plots.json in the workspace (a run of an earlier "
                                         "hmc, or without its report stage): no plots or warnings"},
                                {"markers", nlohmann::json::array()},
                                {"frames", nlohmann::json::array()}});
  }
  // The fixes the track stage applied (hmc track --fixes), if any.
  const fs::path fixes = Stage("track", "track_fixes_used.csv");
  meta["fixes_used"] = IsFile(fixes) ? ReadFile(fixes) : "";
  WriteScript("data/meta.js", "hmcReview.meta(" + meta.dump() + ");\n");
}

ReviewSummary ReviewWriter::Write() {
  const auto start = std::chrono::steady_clock::now();
  const fs::path assets = ReviewAssetsDir();
  shot_ = in_.shot.empty() ? RecordedShot(work_) : in_.shot;
  if (shot_.empty()) {
    ThrowInputError(work_, 0,
                    "the workspace does not record its shot (a run of an earlier hmc): give --shot");
  }
  const fs::path cal = Stage("calibrate", "calibration.yaml");
  if (!IsFile(cal)) ThrowInputError(cal, 0, "the workspace has no calibration: run hmc run first");
  for (const HelmetCamera& c : ReadCalibration(cal).cameras) {
    cameras_.push_back(c.name);
    sizes_.emplace_back(c.camera.width, c.camera.height);
  }
  summary_.cameras = static_cast<int>(cameras_.size());
  ReadTracks();
  ReadStates();
  ReadBundles();
  EnsureDirectory(out_ / "data");
  // The proxies are written beside the mesh data's conversion.
  std::future<void> proxies = std::async(std::launch::async, [this] { WriteProxies(); });
  try {
    WriteTopology();
  } catch (...) {
    proxies.wait();
    throw;
  }
  proxies.get();
  summary_.has_mesh = has_mesh_;
  // The cursor covers the footage, the tracks and the meshes.
  first_ = std::min(first_, footage_first_);
  last_ = std::max(last_, footage_last_);
  if (has_mesh_) {
    first_ = std::min(first_, mesh_start_);
    last_ = std::max(last_, mesh_start_ + mesh_frames_ - 1);
  }
  WriteChunks();
  WriteMeta();
  for (const char* f : {"index.html", "review.js", "review.css", "three.min.js", "OrbitControls.js"}) {
    WriteFileAtomic(out_ / f, ReadFile(assets / f));
  }
  summary_.frames = last_ - first_ + 1;
  summary_.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return summary_;
}

}  // namespace

ReviewSummary WriteReview(const ReviewInput& input, const ReviewOptions& options) {
  if (!options.Check()) throw InputError("invalid review options (see the message above)");
  ReviewSummary summary;
  WriteFolderAtomic(input.out, "hmc review", [&](const fs::path& dir) {
    summary = ReviewWriter(input, options, dir).Write();
  });
  return summary;
}

}  // namespace hmc
