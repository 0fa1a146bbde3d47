// Minimum-cost assignment with a gate: the one assignment solver of the
// tracker (labelling at the reference frame, frame-to-frame matching,
// re-acquisition).
//
// Given costs c(i, j) >= 0 of giving row i (a marker's prediction) column j
// (a detection) and a gate g_i per row, finds the matching that minimises
//
//   sum over matched (i, j) of c(i, j)  +  sum over unmatched rows i of g_i
//
// with every matched pair inside its gate (c(i, j) < g_i), each row and each
// column used at most once. Rows may stay unmatched (at cost g_i), so a
// dot is never forced onto a far detection. Solved exactly by the
// Hungarian method (Kuhn 1955; Munkres 1957) in the shortest-augmenting-path
// form with potentials, O(n^2 m), on the rows extended by one private
// "unmatched" column each. The gate graph is split into connected
// components first, so the cost is that of the largest cluster of dots
// that compete for the same detections, not of the whole image.
#pragma once

#include <vector>

namespace hmc {

struct AssignmentEdge {
  int row = 0;
  int col = 0;
  double cost = 0;  // must be < the row's gate to be usable
};

// Returns, per row, the assigned column or -1. `gates`: one per row (> 0).
// Edges with cost >= their row's gate are ignored; duplicate (row, col)
// edges keep the cheapest.
std::vector<int> SolveGatedAssignment(int num_rows, int num_cols,
                                      const std::vector<AssignmentEdge>& edges,
                                      const std::vector<double>& gates);

// Dense rectangular problem, rows <= cols: minimises sum cost[i][col[i]]
// over injective col. Returns col per row. cost: rows x cols, finite.
std::vector<int> SolveDenseAssignment(const std::vector<std::vector<double>>& cost);

}  // namespace hmc
