#include "tracking/assignment.h"

#include <algorithm>
#include <limits>
#include <map>
#include <numeric>

#include "core/error.h"

namespace hmc {

std::vector<int> SolveDenseAssignment(const std::vector<std::vector<double>>& cost) {
  const int n = static_cast<int>(cost.size());
  if (n == 0) return {};
  const int m = static_cast<int>(cost[0].size());
  if (m < n) throw InputError("SolveDenseAssignment: more rows than columns");
  // e-maxx formulation, 1-based with a virtual column 0.
  const double inf = std::numeric_limits<double>::infinity();
  std::vector<double> u(n + 1, 0), v(m + 1, 0);
  std::vector<int> p(m + 1, 0), way(m + 1, 0);
  for (int i = 1; i <= n; ++i) {
    p[0] = i;
    int j0 = 0;
    std::vector<double> minv(m + 1, inf);
    std::vector<char> used(m + 1, 0);
    do {
      used[j0] = 1;
      const int i0 = p[j0];
      double delta = inf;
      int j1 = 0;
      for (int j = 1; j <= m; ++j) {
        if (used[j]) continue;
        const double cur = cost[i0 - 1][j - 1] - u[i0] - v[j];
        if (cur < minv[j]) {
          minv[j] = cur;
          way[j] = j0;
        }
        if (minv[j] < delta) {
          delta = minv[j];
          j1 = j;
        }
      }
      for (int j = 0; j <= m; ++j) {
        if (used[j]) {
          u[p[j]] += delta;
          v[j] -= delta;
        } else {
          minv[j] -= delta;
        }
      }
      j0 = j1;
    } while (p[j0] != 0);
    do {
      const int j1 = way[j0];
      p[j0] = p[j1];
      j0 = j1;
    } while (j0);
  }
  std::vector<int> col(n, -1);
  for (int j = 1; j <= m; ++j) {
    if (p[j] != 0) col[p[j] - 1] = j - 1;
  }
  return col;
}

namespace {

int Find(std::vector<int>* parent, int x) {
  while ((*parent)[x] != x) {
    (*parent)[x] = (*parent)[(*parent)[x]];
    x = (*parent)[x];
  }
  return x;
}

}  // namespace

std::vector<int> SolveGatedAssignment(int num_rows, int num_cols,
                                      const std::vector<AssignmentEdge>& edges,
                                      const std::vector<double>& gates) {
  if (static_cast<int>(gates.size()) != num_rows) {
    throw InputError("SolveGatedAssignment: one gate per row expected");
  }
  std::vector<int> result(num_rows, -1);
  // Union-find over rows [0, n) and columns [n, n + m) along usable edges.
  std::vector<int> parent(num_rows + num_cols);
  std::iota(parent.begin(), parent.end(), 0);
  std::vector<AssignmentEdge> usable;
  for (const AssignmentEdge& e : edges) {
    if (e.row < 0 || e.row >= num_rows || e.col < 0 || e.col >= num_cols) {
      throw InputError("SolveGatedAssignment: edge out of range");
    }
    if (!(e.cost < gates[e.row])) continue;
    usable.push_back(e);
    const int a = Find(&parent, e.row), b = Find(&parent, num_rows + e.col);
    if (a != b) parent[a] = b;
  }
  std::map<int, std::vector<AssignmentEdge>> components;
  for (const AssignmentEdge& e : usable) components[Find(&parent, e.row)].push_back(e);
  for (auto& [root, list] : components) {
    std::vector<int> rows, cols;
    for (const AssignmentEdge& e : list) {
      rows.push_back(e.row);
      cols.push_back(e.col);
    }
    std::sort(rows.begin(), rows.end());
    rows.erase(std::unique(rows.begin(), rows.end()), rows.end());
    std::sort(cols.begin(), cols.end());
    cols.erase(std::unique(cols.begin(), cols.end()), cols.end());
    const int n = static_cast<int>(rows.size());
    const int m = static_cast<int>(cols.size());
    if (n == 1 && list.size() == 1) {  // the common case: one dot, one detection
      result[list[0].row] = list[0].col;
      continue;
    }
    // Columns: the component's detections, then one "unmatched" column per
    // row (cost = its gate; forbidden for the other rows).
    double big = 0;
    for (int r : rows) big = std::max(big, gates[r]);
    big = 4 * big * (n + 1) + 1;
    std::vector<std::vector<double>> cost(n, std::vector<double>(m + n, big));
    for (int i = 0; i < n; ++i) cost[i][m + i] = gates[rows[i]];
    for (const AssignmentEdge& e : list) {
      const int i = static_cast<int>(std::lower_bound(rows.begin(), rows.end(), e.row) - rows.begin());
      const int j = static_cast<int>(std::lower_bound(cols.begin(), cols.end(), e.col) - cols.begin());
      cost[i][j] = std::min(cost[i][j], e.cost);
    }
    const std::vector<int> col = SolveDenseAssignment(cost);
    for (int i = 0; i < n; ++i) {
      if (col[i] >= 0 && col[i] < m && cost[i][col[i]] < gates[rows[i]]) {
        result[rows[i]] = cols[col[i]];
      }
    }
  }
  return result;
}

}  // namespace hmc
