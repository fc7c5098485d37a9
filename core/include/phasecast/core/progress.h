#pragma once
// Progress of long stages (sampling, SVD, transfer, simulation): a redrawn bar
// with ETA on a terminal, one log line per 10 % otherwise (CI logs, pipes).
// The one progress printer of every tool.

#include <chrono>
#include <cstdio>
#include <string>

namespace phasecast::core {

class ProgressBar {
 public:
  explicit ProgressBar(std::string stage, std::FILE* out = stderr);
  // `detail` follows the counts ("37 state nodes"). All but one unit of the
  // first call's `done` were finished before this run (a resume) and do not
  // count towards the rate the ETA is computed from.
  void update(long done, long total, const std::string& detail = {});
  // Starts a new stage on the same output (a multi-pass computation).
  void restart(std::string stage);
  void finish();
  // No bar prints from now on, in this process: the ranks of an MPI run other
  // than rank 0, whose bars would interleave with its own.
  static void mute_all();

 private:
  std::string stage_;
  std::FILE* out_;
  bool tty_;
  int last_decile_ = -1;
  bool drawn_ = false;
  long first_done_ = -1;
  std::chrono::steady_clock::time_point start_;
};

}  // namespace phasecast::core
