// Test-only: a solve must give bit-identical meshes for any thread count
// (every parallel loop writes its own slot), shared by the solvers' tests.
#pragma once

#include <gtest/gtest.h>

#include <functional>

#include "blending/lgi_solver.h"
#include "core/parallel.h"

namespace hmc {

// Runs `solve` with one and with two worker threads and expects the same
// meshes, bit for bit.
inline void ExpectSameMeshesForAnyThreadCount(
    const std::function<SolveResult()>& solve) {
  SolveResult one, two;
  {
    ThreadLimit limit(1);
    one = solve();
  }
  {
    ThreadLimit limit(2);
    two = solve();
  }
  ASSERT_EQ(one.meshes.size(), two.meshes.size());
  for (size_t f = 0; f < one.meshes.size(); ++f) {
    EXPECT_TRUE(one.meshes[f] == two.meshes[f]) << "frame " << f;
  }
}

}  // namespace hmc
