#include "tracking/assignment.h"

#include <algorithm>
#include <functional>
#include <random>

#include <gtest/gtest.h>

namespace hmc {
namespace {

// Brute force over every partial injective map rows -> cols (or none).
double BestGatedCost(const std::vector<std::vector<double>>& cost, const std::vector<double>& gates) {
  const int n = static_cast<int>(cost.size());
  const int m = n ? static_cast<int>(cost[0].size()) : 0;
  std::vector<char> used(m, 0);
  std::function<double(int)> best = [&](int i) -> double {
    if (i == n) return 0.0;
    double b = gates[i] + best(i + 1);
    for (int j = 0; j < m; ++j) {
      if (used[j] || !(cost[i][j] < gates[i])) continue;
      used[j] = 1;
      b = std::min(b, cost[i][j] + best(i + 1));
      used[j] = 0;
    }
    return b;
  };
  return best(0);
}

TEST(AssignmentTest, GatedMatchesBruteForceOnRandomProblems) {
  for (int seed = 1; seed <= 200; ++seed) {
    std::mt19937 rng(seed);
    const int n = 1 + static_cast<int>(rng() % 6), m = 1 + static_cast<int>(rng() % 6);
    std::uniform_real_distribution<double> uniform(0, 10);
    std::vector<std::vector<double>> cost(n, std::vector<double>(m));
    std::vector<AssignmentEdge> edges;
    std::vector<double> gates(n);
    for (int i = 0; i < n; ++i) {
      gates[i] = uniform(rng);
      for (int j = 0; j < m; ++j) {
        cost[i][j] = uniform(rng);
        edges.push_back({i, j, cost[i][j]});
      }
    }
    const std::vector<int> col = SolveGatedAssignment(n, m, edges, gates);
    double total = 0;
    std::vector<int> uses(m, 0);
    for (int i = 0; i < n; ++i) {
      if (col[i] < 0) {
        total += gates[i];
        continue;
      }
      ASSERT_LT(cost[i][col[i]], gates[i]) << "seed " << seed;
      ASSERT_EQ(++uses[col[i]], 1) << "seed " << seed << ": a column taken twice";
      total += cost[i][col[i]];
    }
    EXPECT_NEAR(total, BestGatedCost(cost, gates), 1e-9) << "seed " << seed;
  }
}

TEST(AssignmentTest, TwoRowsNeverTakeOneColumnAndFarColumnsAreRefused) {
  // Both rows prefer column 0; the optimum gives row 1 column 1.
  const std::vector<AssignmentEdge> edges = {{0, 0, 1.0}, {1, 0, 1.5}, {1, 1, 2.0}, {0, 2, 9.0}};
  const std::vector<int> col = SolveGatedAssignment(2, 3, edges, {3.0, 3.0});
  EXPECT_EQ(col[0], 0);
  EXPECT_EQ(col[1], 1);
  // Alone and outside its gate, a row stays unmatched.
  EXPECT_EQ(SolveGatedAssignment(1, 1, {{0, 0, 5.0}}, {3.0})[0], -1);
}

TEST(AssignmentTest, DenseSolvesAPermutation) {
  const std::vector<std::vector<double>> cost = {{4, 1, 3}, {2, 0, 5}, {3, 2, 2}};
  const std::vector<int> col = SolveDenseAssignment(cost);
  EXPECT_EQ(cost[0][col[0]] + cost[1][col[1]] + cost[2][col[2]], 5);
}

}  // namespace
}  // namespace hmc
