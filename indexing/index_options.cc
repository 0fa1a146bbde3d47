#include "indexing/index_options.h"

#include "core/logging.h"

namespace hmc {

void IndexOptions::Register(OptionFields* fields) {
  fields->SetGroup("index");
  fields->Add("merge_mm", &merge_mm,
              "shapes differing by at most this over a bundle's region share "
              "one cloud point (mm)")
      .AtLeast(0);
  fields->Add("region_tag_mm", &region_tag_mm,
              "shapes tagged for another region are dropped when they move "
              "the bundle's region by at most this (mm)")
      .AtLeast(0);
  fields->Add("min_tet_quality", &min_tet_quality,
              "tetrahedra thinner than this quality are pruned")
      .AtLeast(0).Below(1);
  fields->Add("min_triangle_quality", &min_triangle_quality,
              "triangles thinner than this quality are pruned")
      .AtLeast(0).Below(1);
  fields->Add("max_edge_mm", &max_edge_mm,
              "simplices with a longer edge are pruned (mm; 0 = no bound)")
      .AtLeast(0);
  fields->Add("max_edge_neighbours", &max_edge_neighbours,
              "an edge must join a point to one of its this many nearest "
              "cloud points (0 = no bound; bounds the index of dense clouds)")
      .In(0, 1000);
  fields->Add("grid_max_cells", &grid_max_cells,
              "grid cells along the longest side of a cloud's box")
      .In(1, 256);
  fields->Add("grid_entries_per_element", &grid_entries_per_element,
              "grid memory bound: cell-list entries per element on average")
      .AtLeast(1);
  fields->Add("inside_tolerance", &inside_tolerance,
              "barycentric slack of the inside test")
      .AtLeast(0).Below(0.1);
  fields->Add("on_data_mm", &on_data_mm,
              "distance up to which a bundle counts as on the data (mm)")
      .AtLeast(0);
  fields->SetGroup("");
}

bool IndexOptions::Check() const {
  CHECK_OPTION_LIMITS();
  return true;
}

}  // namespace hmc
