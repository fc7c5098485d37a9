#pragma once
// The real phasecast-server as a child process on endpoints the test chooses
// (server_process.h always takes fresh ports; a restart needs the same
// ones), and waiting on conditions while a tool runs.

#include "child_process.h"

#include <chrono>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace phasecast::testing {

inline constexpr std::chrono::seconds kPatience{60};  // for what should take a second or two

class RealServer {
 public:
  // phasecast-server PACKAGE --cmd CMD --pub PUB EXTRA...; waits for its
  // "listening" line. tcp://127.0.0.1:* takes a free port; pass the
  // announced endpoints to restart on the same ports. Throws with the
  // server's stderr when it does not start.
  RealServer(const std::filesystem::path& package, const std::string& cmd, const std::string& pub,
             const std::filesystem::path& log_stem, std::vector<std::string> extra = {});
  int stop(int signal) { return process_.stop(signal); }
  const std::string& cmd() const { return cmd_; }
  const std::string& pub() const { return pub_; }
  std::string out() const { return process_.out(); }

 private:
  ChildProcess process_;
  std::string cmd_, pub_;
};

// Waits for `done`; false when `tool` ended first or kPatience ran out.
bool wait_until(const std::function<bool()>& done, ChildProcess& tool);

}  // namespace phasecast::testing
