#include "core/parallel.h"

namespace hmc {

ThreadLimit::ThreadLimit(int num_threads) {
  if (num_threads > 0) {
    control_ = std::make_unique<tbb::global_control>(
        tbb::global_control::max_allowed_parallelism,
        static_cast<size_t>(num_threads));
  }
}

}  // namespace hmc
