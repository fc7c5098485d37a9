#include "run_tool.h"

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace phasecast::testing {
namespace {

// Below ctest's --timeout 600 (scripts/test), above the slowest tool run of any test.
constexpr int kPatienceSeconds = 480;

std::string quote(const std::string& word) {
  std::string q = "'";
  for (char c : word) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

}  // namespace

std::filesystem::path tool_path(const std::string& name) {
  const char* dir = std::getenv("PHASECAST_BIN_DIR");
  if (!dir) throw std::runtime_error("PHASECAST_BIN_DIR is not set (run the tests through ctest)");
  return std::filesystem::path(dir) / name;
}

ToolResult run_tool(const std::string& tool, const std::vector<std::string>& args) {
  std::vector<std::string> argv{tool_path(tool).string()};
  argv.insert(argv.end(), args.begin(), args.end());
  return run_command(argv);
}

ToolResult run_command(const std::vector<std::string>& argv) {
  const auto dir = scratch_dir("run_tool_" + std::to_string(::getpid()));
  // A tool that hangs fails its test after kPatienceSeconds, with what it printed,
  // rather than silently at ctest's 600 s timeout.
  std::string cmd = "timeout -k 10 " + std::to_string(kPatienceSeconds) + " ";
  for (const auto& a : argv) cmd += quote(a) + " ";
  cmd += ">" + quote((dir / "out").string()) + " 2>" + quote((dir / "err").string()) + " </dev/null";
  const auto start = std::chrono::steady_clock::now();
  const int status = std::system(cmd.c_str());
  const bool out_of_patience =
      std::chrono::steady_clock::now() - start >= std::chrono::seconds(kPatienceSeconds);
  ToolResult r;
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  r.out = read_file(dir / "out");
  r.err = read_file(dir / "err");
  if (out_of_patience) r.err += "[run_command: killed after " + std::to_string(kPatienceSeconds) + " s]\n";
  return r;
}

pid_t spawn_quietly(std::vector<std::string> argv_s) {
  std::vector<char*> argv;
  for (auto& a : argv_s) argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 1, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_addopen(&actions, 2, "/dev/null", O_WRONLY, 0);
  pid_t pid = 0;
  const int error = posix_spawn(&pid, argv[0], &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (error != 0) throw std::runtime_error("cannot start " + argv_s[0]);
  return pid;
}

std::string read_file(const std::filesystem::path& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::filesystem::path scratch_dir(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() / ("phasecast_test_" + name);
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

}  // namespace phasecast::testing
