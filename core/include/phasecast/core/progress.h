#pragma once
// Progress of long stages: a redrawn bar with ETA on a terminal,
// one log line per 10 % otherwise (CI logs, pipes).

#include <chrono>
#include <cstdio>
#include <string>

namespace phasecast::core {

class ProgressBar {
 public:
  ProgressBar(std::string stage, std::FILE* out = stderr);
  void update(int done, int total);
  void finish();

 private:
  std::string stage_;
  std::FILE* out_;
  bool tty_;
  int last_decile_ = -1;
  bool drawn_ = false;
  std::chrono::steady_clock::time_point start_;
};

}  // namespace phasecast::core
