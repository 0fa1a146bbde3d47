// The state RobustSolver's steps hand each other (blending/robust_solver.h
// numbers the steps; each step's code is in the file named after it, listed
// in docs/method.md "The robust default"). Private to those files.
#pragma once

#include <utility>
#include <vector>

#include <Eigen/Core>

#include "blending/correction_smoothing.h"
#include "blending/robust_solver.h"

namespace hmc {

// One frame's state between the passes.
struct RobustSolver::Work {
  bool ok = false;
  Eigen::VectorXd global;  // the global fit's weights, over its shapes
                           // (BlendshapeSolver::shapes())
  // derived (SetGlobal): the non-zero ones by dataset shape index
  std::vector<std::pair<int, double>> global_nonzero;
  std::vector<Vec3> disp;                  // K observed displacements d_k
  std::vector<char> observed;              // K
  std::vector<char> use_global;            // K
  std::vector<Vec3> residual;              // K: the blend's, at the bundles
  Eigen::MatrixXd alpha;     // K x 3: the kernel's coefficients (empty: none)
  std::vector<Vec3> offset;  // K: interpolated at the bundles (empty: none)

  // shapes: the dataset index of each weight.
  void SetGlobal(Eigen::VectorXd w, const std::vector<int>& shapes) {
    global = std::move(w);
    global_nonzero.clear();
    for (int n = 0; n < global.size(); ++n) {
      if (global[n] != 0) global_nonzero.emplace_back(shapes[n], global[n]);
    }
  }
};

// The state of one sequence solve, handed from step to step.
struct RobustSolver::Sequence {
  explicit Sequence(const std::vector<KernelSmoother>& smoothers)
      : bases(smoothers) {}
  SolveResult result;
  std::vector<Work> work;  // per frame
  std::vector<int> good;   // frames with both fits, in order
  std::vector<const std::vector<char>*> good_observed;  // their observed sets
  CorrectionBases bases;
  // Per good frame, K: the global fit's residuals at the bundles and their
  // leave-one-out counterparts (step 2b).
  std::vector<std::vector<Vec3>> global_residual, global_loo;
  double sigma = 0.0;       // the marker noise (mm)
  double sel_sigma2 = 0.0;  // the noise variance step 3 allows (mm^2)
  int width_index = -1;     // the correction's width (-1: none)
  double lambda = 0.0;      // and its smoothing
  RobustReport report;
};

}  // namespace hmc
