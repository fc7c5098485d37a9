#include "real_server.h"

#include <regex>
#include <stdexcept>
#include <thread>

namespace phasecast::testing {
namespace {

std::vector<std::string> server_arguments(const std::filesystem::path& package, const std::string& cmd,
                                          const std::string& pub, std::vector<std::string> extra) {
  std::vector<std::string> args{package.string(), "--cmd", cmd, "--pub", pub};
  args.insert(args.end(), extra.begin(), extra.end());
  return args;
}

}  // namespace

RealServer::RealServer(const std::filesystem::path& package, const std::string& cmd, const std::string& pub,
                       const std::filesystem::path& log_stem, std::vector<std::string> extra)
    : process_("phasecast-server", server_arguments(package, cmd, pub, std::move(extra)), log_stem) {
  static const std::regex listening(R"(listening cmd=(\S+) pub=(\S+)\n)");
  const auto deadline = std::chrono::steady_clock::now() + kPatience;
  std::smatch m;
  std::string out;
  while (!std::regex_search(out = process_.out(), m, listening)) {
    if (process_.wait(std::chrono::milliseconds(20)) || std::chrono::steady_clock::now() > deadline) {
      throw std::runtime_error("phasecast-server did not start: " + process_.err());
    }
  }
  cmd_ = m[1];
  pub_ = m[2];
}

bool wait_until(const std::function<bool()>& done, ChildProcess& tool) {
  const auto deadline = std::chrono::steady_clock::now() + kPatience;
  while (!done()) {
    if (tool.wait(std::chrono::milliseconds(0)) || std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return true;
}

}  // namespace phasecast::testing
