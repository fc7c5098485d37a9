#pragma once
// A tool (server, gateway) started as a child process for a test, its output
// read through a pipe until it announces where it listens (the server's
// "listening" line, the gateway's "serving" line); stderr kept in a file.

#include <sys/types.h>

#include <functional>
#include <string>
#include <vector>

namespace phasecast::testing {

class ListeningProcess {
 public:
  // Starts argv[0] (a path) with `argv`; `env` entries ("NAME=value") are
  // added to (or replace) the environment. Waits up to 30 s until `ready`
  // accepts what it printed so far; throws, with its standard error, when it
  // exits or stays silent instead.
  ListeningProcess(const std::vector<std::string>& argv, const std::vector<std::string>& env,
                   const std::function<bool(const std::string& out)>& ready);
  ~ListeningProcess();
  ListeningProcess(const ListeningProcess&) = delete;
  ListeningProcess& operator=(const ListeningProcess&) = delete;

  // Sends `signal`, waits, returns the exit code (128 + signal if killed).
  int stop(int signal = 15);
  // Everything it printed on stdout so far (after stop(): all of it).
  std::string out();
  std::string err();
  pid_t pid() const { return pid_; }

 private:
  pid_t pid_ = -1;
  int out_fd_ = -1;
  std::string out_, err_path_;
};

}  // namespace phasecast::testing
