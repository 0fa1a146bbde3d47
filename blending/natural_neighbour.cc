#include "blending/natural_neighbour.h"

#include <cstdint>
#include <cstring>
#include <istream>
#include <ostream>

#include <Eigen/SparseCore>

#include "blending/geodesic_voronoi.h"
#include "blending/voronoi_uv.h"
#include "core/error.h"
#include "core/logging.h"

namespace hmc {

void NaturalNeighbourOptions::Register(OptionFields* fields) {
  fields->Add("domain", &domain,
              "where the Voronoi diagram lives: uv (the UV layout, default) "
              "or geodesic (on the mesh, fast marching)")
      .OneOf({"uv", "geodesic"});
  fields->Add("uv_resolution", &uv_resolution,
              "pixels per side of the UV raster (domain uv)")
      .In(16, 16384);
}

bool NaturalNeighbourOptions::Check() const {
  CHECK_OPTION_LIMITS();
  return true;
}

Eigen::SparseMatrix<double, Eigen::RowMajor> WeightsFromStolenAreas(
    const std::vector<std::vector<std::pair<int, double>>>& stolen,
    const Eigen::VectorXi& cell, int num_sites) {
  const int num_vertices = static_cast<int>(stolen.size());
  HMC_CHECK(cell.size() == num_vertices);
  std::vector<Eigen::Triplet<double>> triplets;
  for (int v = 0; v < num_vertices; ++v) {
    double total = 0.0;
    for (const auto& [k, a] : stolen[v]) total += a;
    if (total > 0) {
      for (const auto& [k, a] : stolen[v]) {
        HMC_CHECK(k >= 0 && k < num_sites);
        triplets.emplace_back(v, k, a / total);
      }
    } else {
      HMC_CHECK(cell[v] >= 0 && cell[v] < num_sites);
      triplets.emplace_back(v, cell[v], 1.0);
    }
  }
  Eigen::SparseMatrix<double, Eigen::RowMajor> weights(num_vertices, num_sites);
  weights.setFromTriplets(triplets.begin(), triplets.end());
  weights.makeCompressed();
  return weights;
}

NaturalNeighbourWeights ComputeNaturalNeighbourWeights(
    const TriMesh& neutral, const std::vector<SurfacePoint>& sites,
    const NaturalNeighbourOptions& options) {
  if (!options.Check()) throw InputError("invalid natural-neighbour options");
  if (sites.empty()) throw InputError("natural-neighbour weights need at least one site");
  StageTimer timer("natural-neighbour weights (" + options.domain + ")");
  if (options.domain == "uv") {
    if (!neutral.HasUVs()) {
      throw InputError("the neutral mesh has no UVs, which the natural-neighbour "
                       "domain 'uv' needs (use domain 'geodesic')");
    }
    return ComputeUvNaturalNeighbourWeights(neutral, sites, options.uv_resolution);
  }
  return ComputeGeodesicNaturalNeighbourWeights(neutral, sites);
}

// Binary layout (little-endian as written by the host): magic "HMCNNW01",
// int64 V, K, nnz; int64 outer[V + 1]; int32 inner[nnz]; double value[nnz];
// per site: int64 count, int32 neighbours[count]; int32 cell[V].
namespace {

constexpr char kMagic[8] = {'H', 'M', 'C', 'N', 'N', 'W', '0', '1'};

template <typename T>
void Put(std::ostream& out, const T& value) {
  out.write(reinterpret_cast<const char*>(&value), sizeof(T));
}
template <typename T>
void PutArray(std::ostream& out, const T* data, size_t n) {
  if (n > 0) out.write(reinterpret_cast<const char*>(data), sizeof(T) * n);
}
template <typename T>
T Get(std::istream& in) {
  T value{};
  if (!in.read(reinterpret_cast<char*>(&value), sizeof(T))) {
    throw InputError("natural-neighbour weights: the data is truncated");
  }
  return value;
}
template <typename T>
void GetArray(std::istream& in, T* data, size_t n) {
  if (n > 0 && !in.read(reinterpret_cast<char*>(data), sizeof(T) * n)) {
    throw InputError("natural-neighbour weights: the data is truncated");
  }
}
void Require(bool ok, const char* what) {
  if (!ok) throw InputError(std::string("natural-neighbour weights: ") + what);
}

}  // namespace

void NaturalNeighbourWeights::Write(std::ostream& out) const {
  HMC_CHECK(weights.isCompressed());
  out.write(kMagic, sizeof(kMagic));
  const int64_t num_vertices = weights.rows(), num_sites = weights.cols();
  const int64_t nnz = weights.nonZeros();
  Put(out, num_vertices);
  Put(out, num_sites);
  Put(out, nnz);
  for (int64_t v = 0; v <= num_vertices; ++v) {
    Put(out, static_cast<int64_t>(weights.outerIndexPtr()[v]));
  }
  for (int64_t i = 0; i < nnz; ++i) {
    Put(out, static_cast<int32_t>(weights.innerIndexPtr()[i]));
  }
  PutArray(out, weights.valuePtr(), nnz);
  HMC_CHECK(static_cast<int64_t>(site_neighbours.size()) == num_sites);
  for (const auto& list : site_neighbours) {
    Put(out, static_cast<int64_t>(list.size()));
    for (int k : list) Put(out, static_cast<int32_t>(k));
  }
  HMC_CHECK(cell.size() == num_vertices);
  for (int64_t v = 0; v < num_vertices; ++v) Put(out, static_cast<int32_t>(cell[v]));
}

NaturalNeighbourWeights NaturalNeighbourWeights::Read(std::istream& in) {
  char magic[sizeof(kMagic)];
  GetArray(in, magic, sizeof(magic));
  Require(std::memcmp(magic, kMagic, sizeof(kMagic)) == 0,
          "not a weights block, or another version");
  const int64_t num_vertices = Get<int64_t>(in);
  const int64_t num_sites = Get<int64_t>(in);
  const int64_t nnz = Get<int64_t>(in);
  Require(num_vertices >= 0 && num_sites >= 0 && nnz >= 0 &&
              num_vertices < (int64_t{1} << 31) && num_sites < (int64_t{1} << 31) &&
              nnz < (int64_t{1} << 40),
          "bad sizes");
  std::vector<int64_t> outer(num_vertices + 1);
  GetArray(in, outer.data(), outer.size());
  Require(outer[0] == 0 && outer[num_vertices] == nnz, "bad row offsets");
  std::vector<int32_t> inner(nnz);
  GetArray(in, inner.data(), inner.size());
  std::vector<double> values(nnz);
  GetArray(in, values.data(), values.size());
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(nnz);
  for (int64_t v = 0; v < num_vertices; ++v) {
    Require(outer[v] <= outer[v + 1], "bad row offsets");
    for (int64_t i = outer[v]; i < outer[v + 1]; ++i) {
      Require(inner[i] >= 0 && inner[i] < num_sites, "site index out of range");
      triplets.emplace_back(static_cast<int>(v), inner[i], values[i]);
    }
  }
  NaturalNeighbourWeights result;
  result.weights.resize(num_vertices, num_sites);
  result.weights.setFromTriplets(triplets.begin(), triplets.end());
  result.weights.makeCompressed();
  result.site_neighbours.resize(num_sites);
  for (auto& list : result.site_neighbours) {
    const int64_t count = Get<int64_t>(in);
    Require(count >= 0 && count <= num_sites, "bad neighbour count");
    list.resize(count);
    for (auto& k : list) {
      k = Get<int32_t>(in);
      Require(k >= 0 && k < num_sites, "neighbour index out of range");
    }
  }
  result.cell.resize(num_vertices);
  for (int64_t v = 0; v < num_vertices; ++v) {
    result.cell[v] = Get<int32_t>(in);
    Require(result.cell[v] >= 0 && result.cell[v] < num_sites, "cell out of range");
  }
  return result;
}

}  // namespace hmc
