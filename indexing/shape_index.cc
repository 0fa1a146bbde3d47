#include "indexing/shape_index.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "core/error.h"
#include "core/parallel.h"
#include "indexing/binary_io.h"

namespace hmc {
namespace {

constexpr char kMagic[8] = {'H', 'M', 'C', 'L', 'G', 'I', 'X', '\0'};
constexpr uint32_t kVersion = 2;  // 2: fields, not padded structs

// max over the region of |b*_a(v) - b*_b(v)| (a or b = -1: the neutral).
double MaxDifferenceOverRegion(const ShapeData& data,
                               const std::vector<int>& region, int a, int b) {
  double worst2 = 0;
  for (int v : region) {
    const float* da_v = a < 0 ? nullptr : data.Displacement(v, a);
    const float* db_v = b < 0 ? nullptr : data.Displacement(v, b);
    double d2 = 0;
    for (int axis = 0; axis < 3; ++axis) {
      const double da = da_v ? da_v[axis] : 0.0;
      const double db = db_v ? db_v[axis] : 0.0;
      d2 += (da - db) * (da - db);
    }
    worst2 = std::max(worst2, d2);
  }
  return std::sqrt(worst2);
}

}  // namespace

bool RegionTagsExclude(const Marker& marker, const Shape& shape) {
  if (shape.tags.empty()) return false;
  for (const auto& tag : shape.tags) {
    if (marker.HasTag(tag)) return false;
  }
  return true;
}

uint64_t Fnv1a64(const std::string& bytes, uint64_t seed) {
  uint64_t h = seed;
  for (unsigned char c : bytes) {
    h ^= c;
    h *= 1099511628211ull;
  }
  return h;
}

ShapeIndex BuildShapeIndex(const Actor& actor, const ShapeData& data,
                           const std::vector<std::vector<int>>& regions,
                           const IndexOptions& options) {
  const int K = data.num_bundles, N = data.num_shapes;
  HMC_CHECK(static_cast<int>(regions.size()) == K);
  ShapeIndex index;
  index.actor_hash = actor.content_hash;
  index.bundles.resize(K);
  index.clouds.resize(K);
  index.represented.resize(K);
  ParallelFor(0, K, [&](int64_t k) {
    std::vector<int> region = regions[k];
    for (int i = 0; i < 3; ++i) {
      region.push_back(actor.neutral.F(data.sites[k].face, i));
    }
    std::sort(region.begin(), region.end());
    region.erase(std::unique(region.begin(), region.end()), region.end());

    CloudStats& stats = index.clouds[k];
    stats.shapes = N;
    std::vector<int> kept = {-1};  // the neutral
    std::vector<std::vector<int>> represented = {{-1}};
    std::vector<Vec3> points = {data.site_neutral.row(k).transpose()};
    for (int n = 0; n < N; ++n) {
      const Vec3 d = data.SiteDisplacement(n, static_cast<int>(k));
      const Vec3 c = data.site_neutral.row(k).transpose() + d;
      if (d.norm() <= options.region_tag_mm &&
          RegionTagsExclude(actor.markers[k], actor.shapes[n]) &&
          MaxDifferenceOverRegion(data, region, n, -1) <=
              options.region_tag_mm) {
        ++stats.pruned_tags;
        represented[0].push_back(n);  // the neutral stands for it
        continue;
      }
      bool merged = false;
      for (size_t i = 0; i < kept.size() && !merged; ++i) {
        if ((c - points[i]).norm() > options.merge_mm) continue;
        if (MaxDifferenceOverRegion(data, region, n, kept[i]) <=
            options.merge_mm) {
          merged = true;
          represented[i].push_back(n);
          if (kept[i] < 0) {
            ++stats.pruned_motion;
          } else {
            ++stats.merged;
          }
        }
      }
      if (merged) continue;
      kept.push_back(n);
      points.push_back(c);
      represented.push_back({n});
    }
    for (auto& list : represented) std::sort(list.begin(), list.end());
    index.represented[k] = represented;
    MatX3d cloud(static_cast<int64_t>(points.size()), 3);
    for (size_t i = 0; i < points.size(); ++i) {
      cloud.row(static_cast<int64_t>(i)) = points[i].transpose();
    }
    index.bundles[k] = BundleIndex::Build(cloud, kept, options);
  });
  return index;
}

int64_t ShapeIndex::MemoryBytes() const {
  int64_t total = 0;
  for (const auto& b : bundles) total += b.stats().memory_bytes;
  return total;
}

void ShapeIndex::Write(std::ostream& out) const {
  out.write(kMagic, sizeof(kMagic));
  WritePod(out, kVersion);
  WritePod(out, actor_hash);
  WritePod(out, options_hash);
  WritePod<uint64_t>(out, bundles.size());
  for (size_t k = 0; k < bundles.size(); ++k) {
    WritePod(out, clouds[k]);
    bundles[k].Write(out);
    WritePod<uint64_t>(out, represented[k].size());
    for (const auto& list : represented[k]) WritePodVector(out, list);
  }
}

ShapeIndex ShapeIndex::Read(std::istream& in) {
  char magic[8];
  in.read(magic, sizeof(magic));
  if (!in || std::memcmp(magic, kMagic, sizeof(magic)) != 0) {
    throw InputError("index cache: not an hmc index file");
  }
  const uint32_t version = ReadPod<uint32_t>(in);
  if (version != kVersion) {
    throw InputError("index cache: format version " + std::to_string(version) +
                     ", expected " + std::to_string(kVersion));
  }
  ShapeIndex index;
  index.actor_hash = ReadPod<uint64_t>(in);
  index.options_hash = ReadPod<uint64_t>(in);
  const uint64_t K = ReadPod<uint64_t>(in);
  if (K > 1000000) throw InputError("index cache: implausible bundle count");
  for (uint64_t k = 0; k < K; ++k) {
    index.clouds.push_back(ReadPod<CloudStats>(in));
    index.bundles.push_back(BundleIndex::Read(in));
    const uint64_t P = ReadPod<uint64_t>(in);
    if (P != static_cast<uint64_t>(index.bundles.back().NumPoints())) {
      throw InputError("index cache: inconsistent represented shapes");
    }
    std::vector<std::vector<int>> lists(P);
    for (auto& list : lists) list = ReadPodVector<int>(in, 1u << 24);
    index.represented.push_back(std::move(lists));
  }
  return index;
}

}  // namespace hmc
