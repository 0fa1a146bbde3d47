// The one wrapper over TBB that parallel loops in hmc go through. Loops
// write results into per-index slots, so output does not depend on the
// thread count or the schedule.
#pragma once

#include <cstdint>
#include <memory>

#include <tbb/blocked_range.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

namespace hmc {

// Limits TBB to `num_threads` for the lifetime of the returned object
// (<= 0: all cores).
class ThreadLimit {
 public:
  explicit ThreadLimit(int num_threads);

 private:
  std::unique_ptr<tbb::global_control> control_;
};

// Calls body(i) for i in [begin, end) in parallel. `body` must only write
// state owned by index i.
template <typename Body>
void ParallelFor(int64_t begin, int64_t end, const Body& body,
                 int64_t grain = 1) {
  if (end <= begin) return;
  tbb::parallel_for(tbb::blocked_range<int64_t>(begin, end, grain),
                    [&](const tbb::blocked_range<int64_t>& range) {
                      for (int64_t i = range.begin(); i != range.end(); ++i) {
                        body(i);
                      }
                    });
}

}  // namespace hmc
