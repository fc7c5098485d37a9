#pragma once
// phasecast-server's transport: a ROUTER command socket and a PUB frame
// socket (docs/protocol.md) around a SynthesisService. The tick runs on its
// own thread at a fixed rate and owns the PUB socket; a command thread owns
// the ROUTER socket; a third answers CURVE authentication (ZAP) when an
// allow-list is given. Neither waits for the other beyond the service's
// lock, and nothing in the tick waits for the disk (docs/server.md).
// ZeroMQ stays inside server.cpp.

#include "phasecast/server/synthesis_service.h"

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace phasecast::server {

struct ServerOptions {
  std::vector<std::filesystem::path> packages;
  // Loopback unless told otherwise: other hosts get in only when asked for
  // (tcp://*:5555), and then preferably with CURVE below.
  std::string cmd_endpoint = "tcp://127.0.0.1:5555";
  std::string pub_endpoint = "tcp://127.0.0.1:5556";
  // The frame endpoint announced to clients (list_scenes), when the bound one is
  // not what they reach: NAT, remapped container ports. Empty: the bound endpoint.
  std::string advertised_pub_endpoint;
  double rate_hz = 60;
  int instances_per_scene = 1;
  std::optional<std::filesystem::path> record;      // record from the start
  std::filesystem::path record_dir = "recordings";  // where record_start requests write
  std::optional<double> blend_lambda;               // overrides every package's lambda
  int pub_high_water_mark = 1000;                   // frames queued per subscriber before drops
  // A connection that has not finished the ZeroMQ handshake (greeting, CURVE)
  // within this many seconds is dropped: idle peers cannot hold the server's
  // descriptors and lock real clients out (docs/security.md).
  double handshake_timeout_s = 5;
  ServiceLimits limits;
  // CURVE (docs/security.md): this server's secret key file turns on
  // authentication and encryption on both sockets; the allow-list, if any,
  // names the client public keys let in (everyone else gets nothing).
  std::optional<std::filesystem::path> curve_secret_key;
  std::optional<std::filesystem::path> allow_clients;
};

// Limits that keep one client from disturbing the others.
inline constexpr int kMaxRequestBytes = 64 * 1024;    // larger requests get an error reply (counted)
inline constexpr int kMaxMessageBytes = 1024 * 1024;  // larger messages drop the peer (ZMQ_MAXMSGSIZE)
inline constexpr int kReplyQueuePerClient = 32;  // replies queued per client (each at most a 1 MiB chunk)

class Server {
 public:
  // Loads the packages, creates the instances and binds both sockets; throws
  // core::PackageError, EngineError or std::runtime_error with one line.
  explicit Server(const ServerOptions& options);
  ~Server();
  Server(const Server&) = delete;
  Server& operator=(const Server&) = delete;

  const std::string& cmd_endpoint() const;  // as bound (ZMQ_LAST_ENDPOINT)
  const std::string& pub_endpoint() const;
  SynthesisService& service();
  // CURVE handshakes refused by the allow-list so far.
  std::uint64_t refused_handshakes() const;

  // Ticks (on the calling thread) and serves commands (on a second thread)
  // until `stop` becomes true, then stops recording (fsync).
  void run(const std::atomic<bool>& stop);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace phasecast::server
