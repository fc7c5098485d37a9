#pragma once
// phasecast-server's transport: a ROUTER command socket and a PUB frame
// socket (docs/protocol.md) around a SynthesisService, driven by one thread
// that ticks at a fixed rate and serves commands in the time between ticks.
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
  std::string cmd_endpoint = "tcp://*:5555";
  std::string pub_endpoint = "tcp://*:5556";
  // The frame endpoint announced to clients (list_scenes), when the bound one is
  // not what they reach: NAT, remapped container ports. Empty: the bound endpoint.
  std::string advertised_pub_endpoint;
  double rate_hz = 60;
  int instances_per_scene = 1;
  std::optional<std::filesystem::path> record;       // record from the start
  std::filesystem::path record_dir = ".";            // where record_start requests write
  std::optional<double> blend_lambda;                // overrides every package's lambda
  int pub_high_water_mark = 1000;                    // frames queued per subscriber before drops
  std::size_t max_instances = kDefaultMaxInstances;  // create_instance refuses beyond this
};

// Limits that keep one client from disturbing the others.
inline constexpr int kMaxRequestBytes = 64 * 1024;  // larger messages drop the peer (ZMQ_MAXMSGSIZE)
inline constexpr int kRequestsPerSlice = 64;        // requests served before the tick is checked again

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

  // Ticks and serves until `stop` becomes true, then stops recording (fsync).
  void run(const std::atomic<bool>& stop);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace phasecast::server
