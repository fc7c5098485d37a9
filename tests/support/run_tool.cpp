#include "run_tool.h"

#include <sys/wait.h>
#include <unistd.h>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace phasecast::testing {
namespace {

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
  const auto dir = scratch_dir("run_tool_" + std::to_string(::getpid()));
  std::string cmd = quote(tool_path(tool).string());
  for (const auto& a : args) cmd += " " + quote(a);
  cmd += " >" + quote((dir / "out").string()) + " 2>" + quote((dir / "err").string()) + " </dev/null";
  const int status = std::system(cmd.c_str());
  ToolResult r;
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  r.out = read_file(dir / "out");
  r.err = read_file(dir / "err");
  return r;
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
