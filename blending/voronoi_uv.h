// The Voronoi diagram of the bundle sites in the neutral's UV layout and the
// discrete natural-neighbour (Sibson) coordinates of the vertices in it
// (Sibson 1980; discrete version: Park et al. 2006, "Discrete Sibson
// interpolation", IEEE TVCG 12(2)).
//
// The domain is the part of the UV square covered by the mesh's UV
// triangles, rasterised at a fixed resolution: the mouth opening and the
// outside of the face are not part of it. Distances are Euclidean in UV.
#pragma once

#include <vector>

#include <Eigen/Core>

#include "blending/natural_neighbour.h"
#include "core/mesh.h"

namespace hmc {

// The UV layout rasterised on square pixels. Pixel (x, y) covers
// origin + [x, x + 1) x [y, y + 1) * pixel_size (y grows with v).
struct UvRaster {
  int width = 0;
  int height = 0;
  double pixel_size = 0.0;  // UV units per pixel side
  Vec2 origin = Vec2::Zero();
  std::vector<int> face;              // W*H: triangle covering the centre, -1: none
  std::vector<Eigen::Vector3f> bary;  // W*H: barycentrics in that triangle

  int Index(int x, int y) const { return y * width + x; }
  Vec2 Centre(int x, int y) const {
    return origin + pixel_size * Vec2(x + 0.5, y + 0.5);
  }
  bool InDomain(int index) const { return face[index] >= 0; }
};

// Rasterises the UV triangles of `mesh` (requires UVs) so that the longer
// side of the UV bounding box spans `resolution` pixels (plus a one-pixel
// margin). Where triangles overlap, the first one wins.
UvRaster RasteriseUvLayout(const TriMesh& mesh, int resolution);

// UV of each site: barycentric interpolation of its triangle's corner UVs.
// Returns K x 2.
MatX2d SiteUVs(const TriMesh& mesh, const std::vector<SurfacePoint>& sites);

// Discrete Voronoi diagram over every pixel of the raster (the natural-
// neighbour insertion needs distances outside the domain too), with a
// quadtree of uniform blocks that lets the insertion count whole blocks.
struct UvVoronoi {
  std::vector<int> label;        // W*H: nearest site (lowest index on ties)
  std::vector<double> distance;  // W*H: UV distance from the centre to it
  // block_code[l]: blocks of 2^l x 2^l pixels, ceil(W / 2^l) per row; the
  // site label if every pixel of the block is in the domain with that label,
  // kOutside if none is in the domain, kMixed otherwise. Level 0 = pixels;
  // the last level is one block.
  static constexpr int kMixed = -1;
  static constexpr int kOutside = -2;
  std::vector<std::vector<int>> block_code;
  MatX2d site_uv;  // K x 2 site positions in UV
};

// site_uv: K x 2 site positions in UV. Exact nearest site per pixel centre.
UvVoronoi ComputeUvVoronoi(const UvRaster& raster, const MatX2d& site_uv);

// Sites whose cells touch inside the domain (two 4-adjacent domain pixels
// with different labels). K lists, sorted.
std::vector<std::vector<int>> UvSiteNeighbours(const UvRaster& raster,
                                               const UvVoronoi& voronoi,
                                               int num_sites);

// Stolen area of a new site inserted at `uv`, per existing site: domain
// pixels p with |p - uv| < d(p) (d: distance to the nearest site), each
// weighted by min(1, (d(p) - |p - uv|) / pixel_size) so that the area varies
// continuously with `uv` below the pixel scale. Returns (site, area in
// pixels) pairs; empty when nothing is stolen (uv on a site).
// Cost: O(boundary of the new cell and of the cells in it), not O(its
// area): the quadtree is walked top-down; a block of one label s is counted
// whole (weight 1) or skipped when its four corner centres decide it (the
// sets {|p - s| - |p - uv| >= c} for c >= 0 are convex), a mixed block is
// skipped when a Lipschitz bound puts it outside the new cell.
std::vector<std::pair<int, double>> UvStolenAreas(const UvRaster& raster,
                                                  const UvVoronoi& voronoi,
                                                  const Vec2& uv);

// The UV variant of ComputeNaturalNeighbourWeights.
NaturalNeighbourWeights ComputeUvNaturalNeighbourWeights(
    const TriMesh& neutral, const std::vector<SurfacePoint>& sites,
    int uv_resolution);

}  // namespace hmc
