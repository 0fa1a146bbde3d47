// The printed pattern of a helmet AprilTag (tag36h11, from the AprilTag
// library's own family tables, so the detector decodes what is drawn) and
// its reflectance on the tag plane, for the footage renderer.
#pragma once

#include <vector>

namespace hmc {

class TagPattern {
 public:
  // Throws InputError if `id` is not a tag36h11 code.
  explicit TagPattern(int id);

  int id() const { return id_; }
  int total_cells() const { return total_cells_; }    // 10: with the white border
  int border_cells() const { return border_cells_; }  // 8: the black square

  // Half the printed plate's edge in units of the tag size (the black-border
  // edge): total / border / 2 = 0.625.
  double PlateHalfExtent() const {
    return 0.5 * total_cells_ / static_cast<double>(border_cells_);
  }

  // 1 (white) or 0 (black) at tag coordinates (x, y), in units of the tag
  // size, origin at the centre, x along columns, y along rows. Points off the
  // plate return -1.
  double Sample(double x, double y) const;

  // The pattern cell (row * total + column) holding (x, y), -1 off the
  // plate. Sample() is constant over a cell, which is convex: samples
  // inside the convex hull of points of one cell need no lookup.
  int Cell(double x, double y) const;

 private:
  int id_ = 0;
  int total_cells_ = 0;
  int border_cells_ = 0;
  std::vector<unsigned char> white_;  // total x total, row-major, 1 = white
};

}  // namespace hmc
