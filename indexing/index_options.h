// Options of the local geometric index (docs/ARCHITECTURE.md, "Method steps", 1-5).
#pragma once

#include "core/options.h"

namespace hmc {

struct IndexOptions {
  // Point clouds (step 1).
  double merge_mm = 1e-4;  // two shapes (the neutral counts as one) share a
                           // cloud point when their unskinned displacements
                           // differ by at most this over the bundle's whole
                           // region of influence (mm); bounds the verification
                           // error this pruning can cause
  double region_tag_mm = 5e-4;  // a shape whose region tags exclude the
                                // marker's is dropped from its cloud when it
                                // moves the region by at most this (mm)
  // Tetrahedra (step 2).
  double min_tet_quality = 0.2;  // 6 sqrt(2) volume / longest edge^3 below
                                 // this: too thin, pruned (0..1)
  double min_triangle_quality = 0.2;  // same for the triangles kept for flat
                                       // clouds (4 area / sqrt(3) edge^2)
  double max_edge_mm = 6.0;  // simplices with a longer edge are pruned as too
                             // large an extent (mm; 0 = no bound)
  int max_edge_neighbours = 0;  // an edge must also join one of its points
                                // to one of its this many nearest cloud
                                // points: in dense clouds the bound shrinks
                                // to the local spacing, so the simplices
                                // grow with the points, not as their 4th
                                // power (0 = no such bound)
  // Grid (step 3).
  int grid_max_cells = 24;  // cells along the longest side of a cloud's box
  double grid_entries_per_element = 8.0;  // memory bound: the grid is made
                                          // coarser until its cell lists hold
                                          // at most this many entries per
                                          // element on average
  // Queries (steps 4-5).
  double inside_tolerance = 1e-9;  // barycentric slack at faces, edges and
                                   // corners (then clamped, renormalised)
  double on_data_mm = 1e-6;  // a point this close to the data counts as
                             // inside (mm)

  void Register(OptionFields* fields);
  bool Check() const;
};

}  // namespace hmc
