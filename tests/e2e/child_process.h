#pragma once
// A tool started in the background (fork/exec), with stdout and stderr going
// to files, so a test can run several renderers at once against one server.

#include <sys/types.h>
#include <chrono>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace phasecast::testing {

class ChildProcess {
 public:
  // Starts $PHASECAST_BIN_DIR/<tool> <args>; output goes to <log_stem>.out/.err.
  ChildProcess(const std::string& tool, const std::vector<std::string>& args,
               const std::filesystem::path& log_stem);
  ~ChildProcess();
  ChildProcess(const ChildProcess&) = delete;
  ChildProcess& operator=(const ChildProcess&) = delete;

  // Exit code once it ended within `timeout` (128 + signal if killed), else nothing.
  std::optional<int> wait(std::chrono::milliseconds timeout);
  // Sends `signal`, then waits for the exit code.
  int stop(int signal);
  std::string out() const;
  std::string err() const;

 private:
  pid_t pid_ = -1;
  std::optional<int> code_;
  std::filesystem::path out_path_, err_path_;
};

}  // namespace phasecast::testing
