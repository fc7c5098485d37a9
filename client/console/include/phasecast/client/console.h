#pragma once
// The scripting console: a Lua 5.4 interpreter whose global functions talk to
// a phasecast-server's command socket (impulses, instances, recording, stats)
// and follow its frame stream (wait_frames). docs/console.md lists the API.

#include "phasecast/client/network.h"

#include <chrono>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>

namespace phasecast::client {

struct ConsoleOptions {
  std::string endpoint = "tcp://127.0.0.1:5555";  // server command socket
  std::chrono::milliseconds timeout{2000};        // per request attempt
  int attempts = 3;                               // Lazy Pirate retries before giving up
  std::chrono::milliseconds frame_timeout{5000};  // wait_frames gives up after this silence
  CurveClientKeys curve;                          // --server-key / --client-key; none: plain connections
};

// A script or chunk failed; what() is "chunk:line: message".
class ScriptError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class Console {
 public:
  explicit Console(ConsoleOptions options);
  ~Console();
  Console(const Console&) = delete;
  Console& operator=(const Console&) = delete;

  // Runs a script file or a chunk of code; throws ScriptError on any error.
  void run_file(const std::filesystem::path& script);
  void run_string(const std::string& code, const std::string& chunk_name);

  // Interactive read-eval-print loop on the terminal (readline, history).
  // Returns at end of input (Ctrl-D).
  void repl();

  // The server's Stats as JSON (proto field names), for scripted sessions
  // that report figures (phasecast-console --stats-out).
  std::string server_stats_json();

  // Async-signal-safe: makes a running wait()/wait_frames() raise "interrupted".
  static void interrupt();

  struct Impl;  // the Lua state and the server connection (console.cpp)

 private:
  std::unique_ptr<Impl> impl_;
};

}  // namespace phasecast::client
