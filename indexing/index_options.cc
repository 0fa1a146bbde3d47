#include "indexing/index_options.h"

#include "core/logging.h"

namespace hmc {

void IndexOptions::Register(OptionFields* fields) {
  fields->SetGroup("index");
  fields->Add("merge_mm", &merge_mm,
              "shapes differing by at most this over a bundle's region share "
              "one cloud point (mm)");
  fields->Add("region_tag_mm", &region_tag_mm,
              "shapes tagged for another region are dropped when they move "
              "the bundle's region by at most this (mm)");
  fields->Add("min_tet_quality", &min_tet_quality,
              "tetrahedra thinner than this quality are pruned (0..1)");
  fields->Add("min_triangle_quality", &min_triangle_quality,
              "triangles thinner than this quality are pruned (0..1)");
  fields->Add("max_edge_mm", &max_edge_mm,
              "simplices with a longer edge are pruned (mm; 0 = no bound)");
  fields->Add("max_edge_neighbours", &max_edge_neighbours,
              "an edge must join a point to one of its this many nearest "
              "cloud points (0 = no bound; bounds the index of dense clouds)");
  fields->Add("grid_max_cells", &grid_max_cells,
              "grid cells along the longest side of a cloud's box");
  fields->Add("grid_entries_per_element", &grid_entries_per_element,
              "grid memory bound: cell-list entries per element on average");
  fields->Add("inside_tolerance", &inside_tolerance,
              "barycentric slack of the inside test");
  fields->Add("on_data_mm", &on_data_mm,
              "distance up to which a bundle counts as on the data (mm)");
  fields->SetGroup("");
}

bool IndexOptions::Check() const {
  CHECK_OPTION_GE(merge_mm, 0.0);
  CHECK_OPTION_GE(region_tag_mm, 0.0);
  CHECK_OPTION_GE(min_tet_quality, 0.0);
  CHECK_OPTION_LT(min_tet_quality, 1.0);
  CHECK_OPTION_GE(min_triangle_quality, 0.0);
  CHECK_OPTION_LT(min_triangle_quality, 1.0);
  CHECK_OPTION_GE(max_edge_mm, 0.0);
  CHECK_OPTION_IN(max_edge_neighbours, 0, 1000);
  CHECK_OPTION_IN(grid_max_cells, 1, 256);
  CHECK_OPTION_GE(grid_entries_per_element, 1.0);
  CHECK_OPTION_GE(inside_tolerance, 0.0);
  CHECK_OPTION_LT(inside_tolerance, 0.1);
  CHECK_OPTION_GE(on_data_mm, 0.0);
  return true;
}

}  // namespace hmc
