#include "blending/solve_method.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>

#include "core/error.h"
#include "core/logging.h"

namespace hmc {

void MethodOptions::Register(OptionFields* fields) {
  build.Register(fields);
  solve.Register(fields);
  blendshape.Register(fields);
  interp.Register(fields);
  lgi_rbf.Register(fields);
  robust.Register(fields);
}

bool MethodOptions::Check() const {
  return build.Check() && solve.Check() && blendshape.Check() &&
         interp.Check() && lgi_rbf.Check() && robust.Check();
}

const std::vector<std::string>& SolveMethodNames() {
  static const std::vector<std::string> names = {
      "robust", "lgi", "blendshape", "blendshape-bounded", "interp",
      "lgi-rbf", "robust-global"};
  return names;
}

std::string SolveMethodList() {
  std::string list;
  for (const std::string& name : SolveMethodNames()) {
    list += (list.empty() ? "" : ", ") + name;
  }
  return list;
}

void CheckSolveMethod(const std::string& name, const std::string& origin) {
  const auto& names = SolveMethodNames();
  if (std::find(names.begin(), names.end(), name) == names.end()) {
    throw InputError(fmt::format("{}: unknown solve method '{}'; valid: {}",
                                 origin, name, SolveMethodList()));
  }
}

namespace {

bool SamePose(const JawPose& a, const JawPose& b) {
  return a.open_deg == b.open_deg && a.lateral_deg == b.lateral_deg &&
         a.protrude_mm == b.protrude_mm;
}

template <typename Memo>
bool SameInputs(const Memo& memo, const std::vector<BundleFrame>& frames,
                const std::vector<JawPose>& jaw,
                const std::vector<std::string>& frame_errors) {
  if (memo.frames.size() != frames.size() || memo.jaw.size() != jaw.size() ||
      memo.frame_errors != frame_errors) {
    return false;
  }
  for (size_t f = 0; f < frames.size(); ++f) {
    if (memo.frames[f].frame != frames[f].frame ||
        memo.frames[f].bundles != frames[f].bundles) {
      return false;
    }
  }
  for (size_t f = 0; f < jaw.size(); ++f) {
    if (!SamePose(memo.jaw[f], jaw[f])) return false;
  }
  return true;
}

}  // namespace

MethodSolvers::MethodSolvers(const Actor& actor, const MethodOptions& options,
                             IndexCacheWrite write_cache)
    : actor_(actor), options_(options), write_cache_(write_cache) {
  // One bad-frame threshold for every method (registered once, as solve's).
  options_.blendshape.min_bundle_fraction = options_.solve.min_bundle_fraction;
  options_.interp.min_bundle_fraction = options_.solve.min_bundle_fraction;
}

MethodSolvers::~MethodSolvers() = default;

const ShapeData& MethodSolvers::data() {
  if (lgi_model_) return lgi_model_->data;
  if (!data_) {
    StageTimer timer("unskinned shapes");
    data_ = std::make_unique<ShapeData>(ComputeShapeData(actor_));
  }
  return *data_;
}

void MethodSolvers::Prepare(const std::string& method) {
  CheckSolveMethod(method, "solve method");
  const bool needs_lgi =
      method == "lgi" || method == "lgi-rbf" || method == "robust" ||
      method == "robust-global";
  if (needs_lgi && !lgi_model_) {
    lgi_model_ = std::make_unique<LgiModel>(
        LoadOrBuildLgiModel(actor_, options_.build.index, options_.build.nn,
                            write_cache_));
  }
  if (needs_lgi && !lgi_) {
    lgi_ = std::make_unique<LgiSolver>(
        actor_.neutral, lgi_model_->data, lgi_model_->index, lgi_model_->nn,
        options_.build.index, options_.solve);
  }
  if (method == "lgi-rbf" && !lgi_rbf_) {
    StageTimer timer("lgi-rbf kernel");
    lgi_rbf_ = std::make_unique<LgiRbfSolver>(actor_.neutral, lgi_model_->data,
                                              *lgi_, options_.lgi_rbf,
                                              options_.interp);
    spdlog::info("lgi-rbf: Gaussian sigma {:.3f} mm", lgi_rbf_->sigma_mm());
  }
  if (method == "blendshape" && !blendshape_) {
    blendshape_ = std::make_unique<BlendshapeSolver>(
        actor_.neutral, data(), options_.blendshape);
  }
  const bool robust_method = method == "robust" || method == "robust-global";
  // The robust default's global fit over a bounded set of shapes when the
  // dataset has more (docs/method.md, "A global fit of bounded size"),
  // else the blendshape-bounded baseline's.
  const bool robust_subset =
      options_.robust.global_shapes > 0 &&
      data().num_shapes > options_.robust.global_shapes;
  if ((method == "blendshape-bounded" || (robust_method && !robust_subset)) &&
      !blendshape_bounded_) {
    BlendshapeOptions bounded = options_.blendshape;
    bounded.bounded = true;
    blendshape_bounded_ =
        std::make_unique<BlendshapeSolver>(actor_.neutral, data(), bounded);
  }
  if (robust_method && robust_subset && !robust_bounded_) {
    BlendshapeOptions bounded = options_.blendshape;
    bounded.bounded = true;
    bounded.max_shapes = options_.robust.global_shapes;
    robust_bounded_ =
        std::make_unique<BlendshapeSolver>(actor_.neutral, data(), bounded);
    spdlog::info("robust: the global fit over {} of {} shapes",
                 robust_bounded_->num_shapes(), data().num_shapes);
  }
  const BlendshapeSolver* robust_global_fit =
      robust_subset ? robust_bounded_.get() : blendshape_bounded_.get();
  if (method == "interp" && !interp_) {
    interp_ = std::make_unique<InterpSolver>(actor_.neutral, data(),
                                             options_.interp);
  }
  if (method == "robust" && !robust_) {
    robust_ = std::make_unique<RobustSolver>(
        actor_.neutral, lgi_model_->data, *lgi_, lgi_model_->nn,
        *robust_global_fit, options_.solve, options_.robust);
  }
  if (method == "robust-global" && !robust_global_) {
    RobustOptions global = options_.robust;
    global.local = false;
    robust_global_ = std::make_unique<RobustSolver>(
        actor_.neutral, lgi_model_->data, *lgi_, lgi_model_->nn,
        *robust_global_fit, options_.solve, global);
  }
}

SolveResult MethodSolvers::Solve(const std::string& method,
                                 const std::vector<BundleFrame>& frames,
                                 const std::vector<JawPose>& jaw,
                                 const std::vector<std::string>& frame_errors,
                                 const MeshSink* sink) {
  if (method == "robust" || method == "robust-global") {
    Prepare(method);
    last_reused_seconds_ = 0.0;
    RobustSolver& solver = method == "robust" ? *robust_ : *robust_global_;
    return solver.SolveSequence(frames, jaw, frame_errors, nullptr, sink);
  }
  SolveResult result = SolveHeld(method, frames, jaw, frame_errors);
  if (sink) DrainMeshes(*sink, &result);
  return result;
}

SolveResult MethodSolvers::SolveHeld(const std::string& method,
                                     const std::vector<BundleFrame>& frames,
                                     const std::vector<JawPose>& jaw,
                                     const std::vector<std::string>& frame_errors) {
  Prepare(method);
  last_reused_seconds_ = 0.0;
  if (method == "lgi") {
    const auto start = std::chrono::steady_clock::now();
    SolveResult result = lgi_->SolveSequence(frames, jaw, frame_errors);
    lgi_memo_ = std::make_unique<LgiMemo>();
    lgi_memo_->frames = frames;
    lgi_memo_->jaw = jaw;
    lgi_memo_->frame_errors = frame_errors;
    lgi_memo_->result = result;
    lgi_memo_->seconds = std::chrono::duration<double>(
                             std::chrono::steady_clock::now() - start)
                             .count();
    return result;
  }
  if (method == "lgi-rbf") {
    if (lgi_memo_ && SameInputs(*lgi_memo_, frames, jaw, frame_errors)) {
      last_reused_seconds_ = lgi_memo_->seconds;
      return lgi_rbf_->SolveFromLgi(lgi_memo_->result);
    }
    return lgi_rbf_->SolveSequence(frames, jaw, frame_errors);
  }
  if (method == "blendshape") {
    return blendshape_->SolveSequence(frames, jaw, frame_errors);
  }
  if (method == "blendshape-bounded") {
    return blendshape_bounded_->SolveSequence(frames, jaw, frame_errors);
  }
  HMC_CHECK(method == "interp");
  return interp_->SolveSequence(frames, jaw, frame_errors);
}

}  // namespace hmc
