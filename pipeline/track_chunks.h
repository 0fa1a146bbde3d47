// A long take tracked in frame chunks (hmc batch --chunk-frames, docs/farm.md
// "Long takes in chunks"): each chunk is an `hmc run --to track` workspace
// of its own, tracked from `overlap` frames before its first frame so that
// its labels and dots are settled when its own frames begin; the take's
// `hmc run --track_chunks FILE` then writes its track stage from the
// chunks' own frames instead of tracking, and runs every later stage on
// the whole take (docs/formats.md, "Track chunks").
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace hmc {

struct TrackChunk {
  std::string work;  // the chunk's hmc run workspace (its track/ holds the tracks)
  int first = 0;     // its own frames, inclusive: what the take keeps of it
  int last = 0;
  int tracked_first = 0;  // the first frame it tracked (first - overlap, within the take)
};

// The chunk list file (JSON: {"chunks": [{"work", "first", "last",
// "tracked_first"}]}). Read throws InputError naming the file for a
// malformed list, chunks out of order or overlapping in their own frames.
void WriteTrackChunks(const std::filesystem::path& file, const std::vector<TrackChunk>& chunks);
std::vector<TrackChunk> ReadTrackChunks(const std::filesystem::path& file);

// The chunk's tracks file: WORK/track/tracks_2d.csv.
std::filesystem::path ChunkTracks(const TrackChunk& chunk);

// Writes into `dir` what the track stage of the whole take holds:
// tracks_2d.csv (each chunk's rows of its own frames, in order),
// options_used.yaml (the first chunk's), diagnostics.json and summary.json
// (the first chunk's labelling; frames, rows and per-view means over the
// merged frames; every chunk's warnings, and per chunk its frames and
// labelling under `chunks`). No footage proxies: the review decodes the
// footage (docs/review.md). Throws InputError naming the chunk whose
// tracks are missing (its task failed or has not run).
void MergeTrackChunks(const std::vector<TrackChunk>& chunks, const std::filesystem::path& dir);

}  // namespace hmc
