#include "synth/tag_render.h"

#include <cmath>

#include <apriltag/apriltag.h>
#include <apriltag/common/image_u8.h>
#include <apriltag/tag36h11.h>

#include "core/error.h"

namespace hmc {

TagPattern::TagPattern(int id) : id_(id) {
  apriltag_family_t* family = tag36h11_create();
  const int num_codes = static_cast<int>(family->ncodes);
  if (id < 0 || id >= num_codes) {
    tag36h11_destroy(family);
    throw InputError("tag id " + std::to_string(id) + " is not a tag36h11 code (0.." +
                     std::to_string(num_codes - 1) + ")");
  }
  image_u8_t* image = apriltag_to_image(family, id);
  total_cells_ = image->width;
  border_cells_ = family->width_at_border;
  white_.resize(static_cast<size_t>(total_cells_) * total_cells_);
  for (int r = 0; r < total_cells_; ++r) {
    for (int c = 0; c < total_cells_; ++c) {
      white_[r * total_cells_ + c] = image->buf[r * image->stride + c] > 127 ? 1 : 0;
    }
  }
  image_u8_destroy(image);
  tag36h11_destroy(family);
}

double TagPattern::Sample(double x, double y) const {
  const double cx = x * border_cells_ + 0.5 * total_cells_;
  const double cy = y * border_cells_ + 0.5 * total_cells_;
  if (!(cx >= 0 && cy >= 0 && cx < total_cells_ && cy < total_cells_)) return -1;
  const int c = static_cast<int>(cx);
  const int r = static_cast<int>(cy);
  return white_[r * total_cells_ + c];
}

int TagPattern::Cell(double x, double y) const {
  const double cx = x * border_cells_ + 0.5 * total_cells_;
  const double cy = y * border_cells_ + 0.5 * total_cells_;
  if (!(cx >= 0 && cy >= 0 && cx < total_cells_ && cy < total_cells_)) return -1;
  return static_cast<int>(cy) * total_cells_ + static_cast<int>(cx);
}

}  // namespace hmc
