#pragma once
// Test helpers for the real phasecast-server: a child process on loopback
// with its announced endpoints, a DEALER command client and a SUB subscriber.

#include "listening_process.h"
#include "phasecast/proto/phasecast.pb.h"

#include <zmq.hpp>

#include <chrono>
#include <optional>
#include <string>
#include <vector>

namespace phasecast::testing {

// phasecast-server <args> --cmd tcp://127.0.0.1:* --pub tcp://127.0.0.1:*,
// started with fork/exec; the constructor waits for the "listening" line.
// `env` entries ("NAME=value") are added to (or replace) the environment.
class ServerProcess {
 public:
  explicit ServerProcess(const std::vector<std::string>& args, const std::vector<std::string>& env = {});

  // Sends `signal`, waits, returns the exit code (128 + signal if killed).
  int stop(int signal = 15) { return process_.stop(signal); }
  const std::string& cmd() const { return cmd_; }
  const std::string& pub() const { return pub_; }
  // Everything the server printed on stdout so far (after stop(): all of it).
  std::string out() { return process_.out(); }
  std::string err() { return process_.err(); }
  pid_t pid() const { return process_.pid(); }

 private:
  std::string cmd_, pub_;  // before process_: its constructor fills them
  ListeningProcess process_;
};

// A CURVE client's keys (Z85 text): the server's public key and its own pair.
struct ClientCurve {
  std::string server_public, client_public, client_secret;
};

// A DEALER that sends [""][Request] and waits for [""][Reply].
class CommandClient {
 public:
  CommandClient(zmq::context_t& context, const std::string& endpoint, const ClientCurve* curve = nullptr);
  v1::Reply call(v1::Request request, std::chrono::milliseconds timeout = std::chrono::seconds(10));
  // Raw multipart send, for malformed inputs.
  void send_raw(const std::vector<std::string>& parts);
  std::optional<v1::Reply> receive(std::chrono::milliseconds timeout);
  zmq::socket_t& socket() { return socket_; }

 private:
  zmq::socket_t socket_;
  std::uint64_t next_id_ = 1;
};

// A SUB socket subscribed to `topic`.
class Subscriber {
 public:
  Subscriber(zmq::context_t& context, const std::string& endpoint, const std::string& topic = "inst/",
             const ClientCurve* curve = nullptr);
  // The next frame, or nothing within `timeout`.
  std::optional<v1::Frame> next(std::chrono::milliseconds timeout = std::chrono::seconds(10));

 private:
  zmq::socket_t socket_;
};

// Convenience request builders.
v1::Request impulse_request(std::uint32_t instance, const std::string& entry);
v1::Request stats_request();

}  // namespace phasecast::testing
