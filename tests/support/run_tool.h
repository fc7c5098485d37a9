#pragma once
// Runs one of our command-line tools as a user would, capturing its exit code,
// standard output and standard error.

#include <sys/types.h>

#include <filesystem>
#include <string>
#include <vector>

namespace phasecast::testing {

struct ToolResult {
  int exit_code = -1;
  std::string out;
  std::string err;
};

// Path of a built tool: $PHASECAST_BIN_DIR/<name> (set by ctest).
std::filesystem::path tool_path(const std::string& name);

// Runs `tool` with `args` (each passed as one shell-quoted word).
ToolResult run_tool(const std::string& tool, const std::vector<std::string>& args);

// Runs any command line (argv[0] found on PATH), capturing as run_tool does.
ToolResult run_command(const std::vector<std::string>& argv);

// Starts argv[0] (a path) with argv, its output discarded, and returns its
// pid without waiting: for tests that kill a run midway.
pid_t spawn_quietly(std::vector<std::string> argv);

// The whole content of a file ("" when it cannot be read).
std::string read_file(const std::filesystem::path& path);

// A fresh empty directory under the system temp dir, named after the test.
std::filesystem::path scratch_dir(const std::string& name);

}  // namespace phasecast::testing
