#include "core/logging.h"

#include <unistd.h>

#include <atomic>
#include <cstdio>
#include <exception>
#include <mutex>

#include <spdlog/sinks/stdout_color_sinks.h>

namespace hmc {

void InitLogging(int verbosity) {
  auto logger = spdlog::stderr_color_mt("hmc");
  logger->set_pattern("%^[%L]%$ %v");
  spdlog::set_default_logger(logger);
  if (verbosity < 0) {
    spdlog::set_level(spdlog::level::warn);
  } else if (verbosity == 0) {
    spdlog::set_level(spdlog::level::info);
  } else if (verbosity == 1) {
    spdlog::set_level(spdlog::level::debug);
  } else {
    spdlog::set_level(spdlog::level::trace);
  }
}

StageTimer::StageTimer(std::string name)
    : name_(std::move(name)), start_(std::chrono::steady_clock::now()) {
  spdlog::info("{}: start", name_);
}

StageTimer::~StageTimer() {
  if (std::uncaught_exceptions() > 0) {
    spdlog::debug("{}: failed after {:.2f} s", name_, ElapsedSeconds());
    return;
  }
  spdlog::info("{}: done in {:.2f} s", name_, ElapsedSeconds());
}

double StageTimer::ElapsedSeconds() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() -
                                       start_)
      .count();
}

struct Progress::State {
  std::atomic<int64_t> done{0};
  std::mutex mutex;
  std::chrono::steady_clock::time_point last_draw;
  bool finished = false;
};

Progress::Progress(std::string label, int64_t total, std::string unit)
    : label_(std::move(label)),
      unit_(std::move(unit)),
      total_(total),
      start_(std::chrono::steady_clock::now()),
      state_(new State),
      enabled_(isatty(STDERR_FILENO) != 0 && total > 1) {}

Progress::~Progress() {
  Finish();
  delete state_;
}

void Progress::Advance(int64_t n) {
  state_->done += n;
  if (!enabled_) return;
  std::unique_lock<std::mutex> lock(state_->mutex, std::try_to_lock);
  if (!lock.owns_lock()) return;
  const auto now = std::chrono::steady_clock::now();
  if (now - state_->last_draw < std::chrono::milliseconds(200)) return;
  state_->last_draw = now;
  Draw(false);
}

void Progress::Finish() {
  std::lock_guard<std::mutex> lock(state_->mutex);
  if (state_->finished) return;
  state_->finished = true;
  if (enabled_) Draw(true);
}

void Progress::Draw(bool final_line) {
  const int64_t done = state_->done.load();
  const double elapsed_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start_)
          .count();
  const double rate = elapsed_s > 0 ? done / elapsed_s : 0.0;
  const double eta_s = rate > 0 ? (total_ - done) / rate : 0.0;
  std::fprintf(stderr, "\r%s  %lld/%lld %s  %.1f/s  %s %.0f s   %s",
               label_.c_str(), static_cast<long long>(done),
               static_cast<long long>(total_), unit_.c_str(), rate,
               final_line ? "took" : "ETA", final_line ? elapsed_s : eta_s,
               final_line ? "\n" : "");
  std::fflush(stderr);
}

}  // namespace hmc
