// The day's markers (core/day_markers.h) against the solve's index cache
// (blending/solve_index_cache.h): an actor loaded with another marker set
// has another content hash, so its index is cached apart from the
// package's; the same markers give the same key.
#include <algorithm>
#include <filesystem>
#include <string>

#include <gtest/gtest.h>

#include "blending/solve_index_cache.h"
#include "core/day_markers.h"
#include "core/error.h"
#include "core/file_util.h"
#include "core/temp_dir.h"
#include "synth/paint.h"
#include "synth/synth_actor.h"

namespace hmc {
namespace {

// A small synthetic package written to dir/actor, loaded back.
Actor SmallPackage(const std::filesystem::path& dir, int seed) {
  SynthActorOptions options;
  options.seed = seed;
  options.grid_u = 48;
  options.grid_v = 40;
  options.dataset_inbetweens = false;
  options.dataset_combos = false;
  WriteActor(SynthesizeActor(options), dir / "actor", 17);
  return LoadActor(dir / "actor");
}

TEST(DayMarkersCache, CacheKeyFollowsTheMarkerSet) {
  for (const int seed : {3, 11}) {
    TempDir dir("hmc_day_markers_cache");
    const Actor package = SmallPackage(dir.path(), seed);
    PaintOptions paint;
    paint.jitter_mm = 1.5;
    const PaintedDots painted = PaintDots(package.neutral, package.markers, paint, seed);
    const std::filesystem::path day_file = dir.path() / "day.csv";
    WriteFileAtomic(day_file, FormatMarkersCsv(painted.markers, nullptr));
    const Actor day = WithDayMarkers(package, day_file);
    // The day's markers are the painted points, read back.
    ASSERT_EQ(day.markers.size(), package.markers.size());
    double moved = 0;
    for (size_t k = 0; k < day.markers.size(); ++k) {
      const Vec3 a = EvaluateSurfacePoint(day.markers[k].point, day.neutral.F, day.neutral.V);
      const Vec3 b =
          EvaluateSurfacePoint(painted.markers[k].point, package.neutral.F, package.neutral.V);
      EXPECT_LT((a - b).norm(), 1e-9) << day.markers[k].name;
      moved = std::max(moved, (a - EvaluateSurfacePoint(package.markers[k].point,
                                                        package.neutral.F, package.neutral.V))
                                  .norm());
    }
    EXPECT_GT(moved, 0.5);
    const uint64_t options_hash = IndexOptionsHash(IndexOptions(), NaturalNeighbourOptions());
    EXPECT_NE(day.content_hash, package.content_hash);
    EXPECT_NE(UserIndexCachePath(day, options_hash), UserIndexCachePath(package, options_hash));
    // The same file again: the same key; the package's own markers as a day
    // file: a key of their own (a day file is a marker set, named by its text).
    EXPECT_EQ(WithDayMarkers(package, day_file).content_hash, day.content_hash);
    const std::filesystem::path same_file = dir.path() / "same.csv";
    WriteFileAtomic(same_file, FormatMarkersCsv(package.markers, nullptr));
    EXPECT_NE(WithDayMarkers(package, same_file).content_hash, day.content_hash);
  }
}

TEST(DayMarkersCache, BadMarkersFileIsNamed) {
  TempDir dir("hmc_day_markers_bad");
  const Actor package = SmallPackage(dir.path(), 1);
  const std::filesystem::path bad = dir.path() / "bad.csv";
  WriteFileAtomic(bad, "name,vertex,face,weights,tags\nm0,,999999,0.2 0.3 0.5,\n");
  try {
    WithDayMarkers(package, bad);
    FAIL() << "a marker off the mesh was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("bad.csv"), std::string::npos) << e.what();
  }
  EXPECT_THROW(WithDayMarkers(package, dir.path() / "missing.csv"), InputError);
}

}  // namespace
}  // namespace hmc
