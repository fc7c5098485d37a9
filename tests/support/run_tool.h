#pragma once
// Runs one of our command-line tools as a user would, capturing its exit code,
// standard output and standard error.

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

// The whole content of a file ("" when it cannot be read).
std::string read_file(const std::filesystem::path& path);

// A fresh empty directory under the system temp dir, named after the test.
std::filesystem::path scratch_dir(const std::string& name);

}  // namespace phasecast::testing
