#include "pipeline/track_chunks.h"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "core/error.h"
#include "core/file_util.h"
#include "core/tracks_2d.h"

namespace hmc {

namespace fs = std::filesystem;

void WriteTrackChunks(const fs::path& file, const std::vector<TrackChunk>& chunks) {
  nlohmann::json list = nlohmann::json::array();
  for (const TrackChunk& c : chunks) {
    list.push_back({{"work", c.work},
                    {"first", c.first},
                    {"last", c.last},
                    {"tracked_first", c.tracked_first}});
  }
  EnsureDirectory(file.parent_path());
  WriteFileAtomic(file, nlohmann::json{{"chunks", list}}.dump(1) + "\n");
}

std::vector<TrackChunk> ReadTrackChunks(const fs::path& file) {
  const std::string problem = DescribeUnreadable(file);
  if (!problem.empty()) ThrowInputError(file, 0, "--track_chunks {}", problem);
  const nlohmann::json json = nlohmann::json::parse(ReadFile(file), nullptr, false);
  if (!json.is_object() || !json.contains("chunks") || !json["chunks"].is_array() ||
      json["chunks"].empty()) {
    ThrowInputError(file, 0, "not a list of track chunks (expected {{\"chunks\": [...]}})");
  }
  std::vector<TrackChunk> chunks;
  try {
    for (const auto& c : json["chunks"]) {
      chunks.push_back({c.at("work").get<std::string>(), c.at("first").get<int>(),
                        c.at("last").get<int>(), c.at("tracked_first").get<int>()});
    }
  } catch (const nlohmann::json::exception& e) {
    ThrowInputError(file, 0, "damaged list of track chunks: {}", e.what());
  }
  for (size_t i = 0; i < chunks.size(); ++i) {
    const TrackChunk& c = chunks[i];
    if (c.last < c.first || c.tracked_first > c.first ||
        (i > 0 && c.first != chunks[i - 1].last + 1)) {
      ThrowInputError(file, 0,
                      "chunk {} (frames {}-{}, tracked from {}) does not follow the one before: "
                      "chunks must tile the take in order",
                      i, c.first, c.last, c.tracked_first);
    }
  }
  return chunks;
}

fs::path ChunkTracks(const TrackChunk& chunk) {
  return fs::path(chunk.work) / "track" / "tracks_2d.csv";
}

void MergeTrackChunks(const std::vector<TrackChunk>& chunks, const fs::path& dir) {
  std::vector<Track2d> tracks;
  nlohmann::json merged;
  nlohmann::json frames = nlohmann::json::array();
  nlohmann::json chunk_list = nlohmann::json::array();
  nlohmann::json warnings = nlohmann::json::array();
  std::error_code ec;
  for (size_t i = 0; i < chunks.size(); ++i) {
    const TrackChunk& c = chunks[i];
    const fs::path file = ChunkTracks(c);
    const fs::path diagnostics = fs::path(c.work) / "track" / "diagnostics.json";
    if (!fs::is_regular_file(file, ec) || !fs::is_regular_file(diagnostics, ec)) {
      ThrowInputError(file, 0,
                      "chunk {} of the take (frames {}-{}) has no tracks: its task failed or has "
                      "not run (hmc batch runs it again)",
                      i, c.first, c.last);
    }
    for (const Track2d& row : ReadTracks2dCsv(file)) {
      if (row.frame >= c.first && row.frame <= c.last) tracks.push_back(row);
    }
    nlohmann::json d = nlohmann::json::parse(ReadFile(diagnostics), nullptr, false);
    if (!d.is_object()) ThrowInputError(diagnostics, 0, "damaged: not a JSON object");
    for (const auto& f : d.value("frames", nlohmann::json::array())) {
      const int frame = f.value("frame", 0);
      if (frame >= c.first && frame <= c.last) frames.push_back(f);
    }
    for (const auto& w : d.value("warnings", nlohmann::json::array())) {
      warnings.push_back(fmt::format("chunk {} (frames {}-{}): {}", i, c.first, c.last,
                                     w.get<std::string>()));
    }
    chunk_list.push_back({{"first", c.first},
                          {"last", c.last},
                          {"tracked_first", c.tracked_first},
                          {"reference_frame", d.value("reference_frame", 0)},
                          {"labelling", d.value("labelling", nlohmann::json::object())},
                          {"never_found", d.value("never_found", nlohmann::json::array())}});
    if (i == 0) {
      merged = d;
      fs::copy_file(fs::path(c.work) / "track" / "options_used.yaml", dir / "options_used.yaml",
                    fs::copy_options::overwrite_existing, ec);
    }
  }
  // The summary over the merged frames, from their per-frame entries.
  int64_t views = 0, skipped = 0, detections = 0, named = 0, reacquired = 0, swaps = 0;
  for (const auto& f : frames) {
    // (the cameras held by name: items() of a temporary would dangle)
    const nlohmann::json cameras = f.value("cameras", nlohmann::json::object());
    for (const auto& [camera, t] : cameras.items()) {
      reacquired += t.value("reacquired", 0);
      swaps += t.value("swaps_caught", 0);
      if (t.value("skipped", false)) {
        ++skipped;
        continue;
      }
      ++views;
      detections += t.value("detections", 0);
      named += t.value("named", 0);
    }
  }
  nlohmann::json summary = merged.value("summary", nlohmann::json::object());
  summary["frames"] = frames.size();
  summary["skipped_views"] = skipped;
  summary["mean_detections"] = views ? static_cast<double>(detections) / views : 0.0;
  summary["mean_named"] = views ? static_cast<double>(named) / views : 0.0;
  summary["reacquired"] = reacquired;
  summary["swaps_caught"] = swaps;
  summary["rows"] = tracks.size();
  merged["summary"] = summary;
  merged["warnings"] = warnings;
  merged["chunks"] = chunk_list;
  merged.erase("frames");
  WriteTracks2dCsv(dir / "tracks_2d.csv", std::move(tracks));
  nlohmann::json with_frames = merged;
  with_frames["frames"] = frames;
  WriteFileAtomic(dir / "diagnostics.json", with_frames.dump(1));
  WriteFileAtomic(dir / "summary.json", merged.dump(1) + "\n");  // last
}

}  // namespace hmc
