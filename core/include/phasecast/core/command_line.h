#pragma once
// The command line of every Phasecast tool: --help prints the options, and a
// command-line error (unknown option, value that does not convert or fails its
// check, missing argument, missing file) is one line naming the tool, as every
// other error is, with exit status 2 (bad usage), never CLI11's two lines and
// its own codes. Header-only: each tool links CLI11, the core library does not.

#include <CLI/CLI.hpp>

#include <iostream>
#include <optional>
#include <string_view>

namespace phasecast::core {

inline constexpr int kUsageExitStatus = 2;

// Parses argv into app. Returns the status to exit with when the tool should
// stop here (0 after --help or --version, kUsageExitStatus after an error),
// std::nullopt when it should go on.
inline std::optional<int> parse_command_line(CLI::App& app, int argc, const char* const* argv,
                                             std::string_view tool) {
  try {
    app.parse(argc, argv);
  } catch (const CLI::Success& e) {  // --help, --help-all, --version
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::cerr << tool << ": " << e.what() << " (see --help)\n";
    return kUsageExitStatus;
  }
  return std::nullopt;
}

}  // namespace phasecast::core
