// The one place that maps a solve method's name to a sequence solve
// (docs/ARCHITECTURE.md, "Method steps"; docs/baselines.md), so `hmc solve --method` and `hmc experiment`
// run every method the same way: the same inputs (actor, bundle frames, jaw
// poses, per-frame errors) and the same output (SolveResult: one mesh per
// frame plus FrameSolve diagnostics; bad frames repeat the previous good
// mesh).
//
// Methods: "robust" (blending/robust_solver.h, the default of `hmc solve`),
// "lgi" (blending/lgi_solver.h), "blendshape" and
// "blendshape-bounded" (blending/baseline_blendshape.h), "interp"
// (blending/baseline_interp.h), "lgi-rbf" (blending/lgi_rbf.h),
// "robust-global" (robust without the local data, robust.local false: what
// `hmc experiment` measures the local data's gain against).
//
// MethodSolvers holds the per-actor precomputation (unskinned shapes, the
// lgi index and natural-neighbour weights, the baselines' normal matrices
// and kernels), built on first use of a method and reused for every later
// sequence, so an experiment that solves many materials with each method
// builds each only once.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "blending/baseline_blendshape.h"
#include "blending/baseline_interp.h"
#include "blending/lgi_rbf.h"
#include "blending/lgi_solver.h"
#include "blending/robust_solver.h"
#include "blending/solve_index_cache.h"
#include "core/actor.h"
#include "core/options.h"

namespace hmc {

// Options of every method, each in its group: index, nn (the lgi index and
// its cache), solve (lgi per frame; also the choices lgi-rbf and robust
// use), blendshape, interp, lgi_rbf, robust.
struct MethodOptions {
  LgiBuildOptions build;
  SolveOptions solve;
  BlendshapeOptions blendshape;
  InterpOptions interp;
  LgiRbfOptions lgi_rbf;
  RobustOptions robust;

  void Register(OptionFields* fields);
  bool Check() const;
};

// The valid method names, in the order of docs/baselines.md.
const std::vector<std::string>& SolveMethodNames();

// "lgi, blendshape, ..." for help texts and messages.
std::string SolveMethodList();

// Throws InputError naming `name` and listing the valid methods unless
// `name` is one of them. `origin`: where the name came from ("--method").
void CheckSolveMethod(const std::string& name, const std::string& origin);

class MethodSolvers {
 public:
  // actor must outlive this object. write_cache: where the lgi model goes
  // when it had to be built (blending/solve_index_cache.h; never the
  // package for a solve).
  MethodSolvers(const Actor& actor, const MethodOptions& options,
                IndexCacheWrite write_cache);
  ~MethodSolvers();

  // Builds what `method` needs (once) without solving.
  void Prepare(const std::string& method);

  // Solves a sequence with `method` (CheckSolveMethod first). jaw: one pose
  // per frame or empty; frame_errors: empty or one per frame, a non-empty
  // entry marks that frame bad. sink (optional): the meshes go to it in
  // frame order and the result holds none (blending/frame_solve.h); the
  // robust methods hand each over as it is blended, so that they are never
  // all held, the others when their sequence is solved.
  SolveResult Solve(const std::string& method,
                    const std::vector<BundleFrame>& frames,
                    const std::vector<JawPose>& jaw,
                    const std::vector<std::string>& frame_errors = {},
                    const MeshSink* sink = nullptr);

  // Wall time of earlier work a Solve reused: lgi-rbf on the inputs of the
  // previous lgi solve reuses its per-bundle choices (s; 0 otherwise).
  double last_reused_seconds() const { return last_reused_seconds_; }

  // The lgi model if a method that needs it was prepared, else nullptr.
  const LgiModel* lgi_model() const { return lgi_model_.get(); }
  // The unskinned dataset shared by all methods (built on first need).
  const ShapeData& data();

 private:
  // Solve for the methods that hold every mesh until their sequence is
  // solved (all but the robust ones).
  SolveResult SolveHeld(const std::string& method,
                        const std::vector<BundleFrame>& frames,
                        const std::vector<JawPose>& jaw,
                        const std::vector<std::string>& frame_errors);

  const Actor& actor_;
  MethodOptions options_;
  IndexCacheWrite write_cache_ = IndexCacheWrite::kNone;
  std::unique_ptr<LgiModel> lgi_model_;
  std::unique_ptr<ShapeData> data_;  // when no lgi model is needed
  std::unique_ptr<LgiSolver> lgi_;
  std::unique_ptr<LgiRbfSolver> lgi_rbf_;
  std::unique_ptr<BlendshapeSolver> blendshape_;
  std::unique_ptr<BlendshapeSolver> blendshape_bounded_;
  // The robust default's global fit when robust.global_shapes selects fewer
  // than every shape (else it shares blendshape_bounded_).
  std::unique_ptr<BlendshapeSolver> robust_bounded_;
  std::unique_ptr<InterpSolver> interp_;
  std::unique_ptr<RobustSolver> robust_;
  std::unique_ptr<RobustSolver> robust_global_;  // robust.local false
  // The last lgi solve, for lgi-rbf on the same inputs.
  struct LgiMemo {
    std::vector<BundleFrame> frames;
    std::vector<JawPose> jaw;
    std::vector<std::string> frame_errors;
    SolveResult result;
    double seconds = 0.0;
  };
  std::unique_ptr<LgiMemo> lgi_memo_;
  double last_reused_seconds_ = 0.0;
};

}  // namespace hmc
