// One logger for hmc: spdlog's default logger, on stderr. Stage start/end
// lines at info, per-frame detail at debug ("-v"), and trace ("-vv").
#pragma once

#include <chrono>
#include <cstdint>
#include <string>

#include <spdlog/spdlog.h>

namespace hmc {

// verbosity: 0 = info, 1 = debug, 2 = trace, -1 = warnings only.
void InitLogging(int verbosity);

// Logs "<name>: start" now and "<name>: done in X s" when destroyed (not
// when destroyed by an exception: the error message says what happened).
class StageTimer {
 public:
  explicit StageTimer(std::string name);
  ~StageTimer();
  double ElapsedSeconds() const;

 private:
  std::string name_;
  std::chrono::steady_clock::time_point start_;
};

// Progress of long work on a terminal: "label  done/total  rate/s  ETA".
// Prints to stderr only when stderr is a terminal; silent otherwise.
// Thread-safe: Advance() may be called from parallel loops.
class Progress {
 public:
  Progress(std::string label, int64_t total, std::string unit = "frames");
  ~Progress();
  void Advance(int64_t n = 1);
  void Finish();

 private:
  void Draw(bool final_line);
  std::string label_;
  std::string unit_;
  int64_t total_;
  std::chrono::steady_clock::time_point start_;
  struct State;
  State* state_;
  bool enabled_;
};

}  // namespace hmc
