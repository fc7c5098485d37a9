// phasecast-console: send impulses and script sessions in Lua (docs/console.md).

#include "phasecast/client/console.h"
#include "phasecast/client/curve_options.h"

#include <fmt/format.h>
#include "phasecast/core/command_line.h"

#include <CLI/CLI.hpp>

#include <unistd.h>
#include <csignal>
#include <fstream>
#include <iostream>
#include <iterator>

namespace {

extern "C" void on_sigint(int) {
  phasecast::client::Console::interrupt();
}

void write_stats(phasecast::client::Console& console, const std::string& path) {
  std::ofstream out(path);
  out << console.server_stats_json() << '\n';
  if (!out.flush()) throw std::runtime_error(fmt::format("--stats-out {}: cannot write the file", path));
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "Phasecast scripting console: Lua 5.4 with functions that send impulses to a "
      "phasecast-server and follow its instances. Runs a script file, -e code, a script on "
      "standard input, or an interactive prompt on a terminal."};
  phasecast::client::ConsoleOptions options;
  std::string script;
  std::vector<std::string> code;
  std::string stats_out;
  int timeout_ms = 2000;
  app.add_option("--connect", options.endpoint, "server command endpoint")->capture_default_str();
  app.add_option("--timeout", timeout_ms, "milliseconds to wait for each reply before retrying")
      ->check(CLI::Range(1, 600000))
      ->capture_default_str();
  app.add_option("--attempts", options.attempts, "tries per request before giving up")
      ->check(CLI::Range(1, 100))
      ->capture_default_str();
  // One chunk per -e, so that `-e CODE script.lua` does not read the script path as code.
  app.add_option("-e,--execute", code, "Lua code to run (repeatable, runs before the script)")
      ->allow_extra_args(false);
  app.add_option("--stats-out", stats_out, "after the script, write the server's stats as JSON to this file");
  phasecast::client::CurveKeyFiles keys;
  phasecast::client::add_curve_options(app, keys);
  app.add_option("script", script, "Lua script file")->check(CLI::ExistingFile);
  if (const auto status = phasecast::core::parse_command_line(app, argc, argv, "phasecast-console"))
    return *status;
  options.timeout = std::chrono::milliseconds(timeout_ms);

  try {
    options.curve = phasecast::client::load_curve_client_keys(keys.server_key, keys.client_key);
    phasecast::client::Console console(options);
    for (const auto& chunk : code) console.run_string(chunk, "=(command line)");
    if (!script.empty()) {
      console.run_file(script);
    } else if (code.empty()) {
      if (isatty(STDIN_FILENO)) {
        // In the REPL, Ctrl-C cancels the running wait instead of ending the console.
        struct sigaction sa {};
        sa.sa_handler = on_sigint;
        sigemptyset(&sa.sa_mask);
        sigaction(SIGINT, &sa, nullptr);
        console.repl();
      } else {
        const std::string input{std::istreambuf_iterator<char>(std::cin), {}};
        console.run_string(input, "=stdin");
      }
    }
    if (!stats_out.empty()) write_stats(console, stats_out);
  } catch (const std::exception& e) {
    fmt::print(stderr, "phasecast-console: {}\n", e.what());
    return 1;
  }
  return 0;
}
