#include "server_flags.h"

namespace phasecast::server::tools {

void add_server_options(CLI::App& app, ServerFlags& f) {
  app.add_option("packages", f.packages, "scene packages (.h5), one scene each")
      ->required()
      ->check(CLI::ExistingFile);
  app.add_option(
         "--cmd", f.options.cmd_endpoint,
         "ROUTER command endpoint to bind (loopback by default; tcp://*:5555 opens it to other hosts)")
      ->capture_default_str();
  app.add_option("--pub", f.options.pub_endpoint, "PUB frame endpoint to bind (loopback by default)")
      ->capture_default_str();
  app.add_option("--advertise-pub", f.options.advertised_pub_endpoint,
                 "frame endpoint clients are told to subscribe to (default: the bound --pub), e.g. "
                 "tcp://public-host:7556 behind NAT or remapped ports")
      ->check([](const std::string& e) {
        return e.rfind("tcp://", 0) == 0 || e.rfind("ipc://", 0) == 0 || e.rfind("inproc://", 0) == 0
                   ? std::string()
                   : "expected a ZeroMQ endpoint such as tcp://host:port, got '" + e + "'";
      });
  app.add_option("--rate", f.options.rate_hz, "tick rate, Hz")
      ->check(CLI::Range(1e-3, 1e4))
      ->capture_default_str();
  app.add_option("--instances", f.options.instances_per_scene, "instances created per scene at start")
      ->check(CLI::Range(0, 1000000))
      ->capture_default_str();
  app.add_option("--record", f.record, "record the published stream to this file from the start");
  app.add_option("--record-dir", f.options.record_dir,
                 "directory for recordings started by record_start requests (created on first use; give it a "
                 "folder of its own: clients name files in it)")
      ->capture_default_str();
  app.add_option("--record-max-bytes", f.options.limits.record_max_bytes,
                 "a recording ends (with a reason, the stream goes on) before it passes this size")
      ->check(CLI::Range(std::uint64_t{1} << 20, ~std::uint64_t{0}))
      ->capture_default_str();
  app.add_option("--blend-lambda", f.lambda, "override the packages' eq. 12 blend rate lambda, 1/s")
      ->check(CLI::Range(0.0, 1e9));
  app.add_option("--hwm", f.options.pub_high_water_mark,
                 "frames queued per subscriber before it loses frames")
      ->check(CLI::Range(1, 10000000))
      ->capture_default_str();
  app.add_option("--max-instances", f.options.limits.max_instances,
                 "create_instance requests beyond this many instances in all are refused")
      ->check(CLI::Range(1, 1000000))
      ->capture_default_str();
  app.add_option("--max-instances-per-client", f.options.limits.max_instances_per_client,
                 "instances one client (CURVE key, else connection) may have created and not destroyed")
      ->check(CLI::Range(1, 1000000))
      ->capture_default_str();
  app.add_option("--impulse-horizon", f.options.limits.impulse_horizon_s,
                 "how far ahead an impulse's at_frame may lie, seconds")
      ->check(CLI::Range(0.0, 1e7))
      ->capture_default_str();
  app.add_option("--max-request-rate", f.options.limits.max_request_rate,
                 "requests per second one client may send (bursts of one second's worth)")
      ->check(CLI::Range(1.0, 1e9))
      ->capture_default_str();
  app.add_option("--max-pending-reply-bytes", f.options.limits.max_pending_reply_bytes,
                 "reply bytes queued for all clients together (slow readers); basis chunks past it are "
                 "refused")
      ->check(CLI::Range(std::uint64_t{1} << 20, ~std::uint64_t{0}))
      ->capture_default_str();
  app.add_option("--max-pending-reply-bytes-per-client", f.options.limits.max_pending_reply_bytes_per_client,
                 "reply bytes queued for one client (CURVE key, else connection); its basis chunks past it "
                 "are refused")
      ->check(CLI::Range(std::uint64_t{1} << 20, ~std::uint64_t{0}))
      ->capture_default_str();
  app.add_option("--handshake-timeout", f.options.handshake_timeout_s,
                 "seconds a new connection has to finish the ZeroMQ handshake before it is dropped (idle "
                 "peers cannot hold the descriptors real clients need)")
      ->capture_default_str();
  app.add_option("--curve-secret-key", f.secret_key,
                 "this server's CURVE secret key file (NAME.key from phasecast-keygen): encrypts and "
                 "authenticates both sockets")
      ->check(CLI::ExistingFile);
  app.add_option("--allow-clients", f.allow_clients,
                 "file of client public keys (NAME.pub lines) let in; others get nothing (needs "
                 "--curve-secret-key)")
      ->check(CLI::ExistingFile);
  app.add_option("--replay-check", f.replay, "verify that this recording replays bit for bit, then exit")
      ->check(CLI::ExistingFile);
}

ServerOptions ServerFlags::resolved() const {
  ServerOptions o = options;
  for (const auto& p : packages) o.packages.emplace_back(p);
  if (!secret_key.empty()) o.curve_secret_key = secret_key;
  if (!allow_clients.empty()) o.allow_clients = allow_clients;
  if (!record.empty()) o.record = record;
  if (lambda >= 0) o.blend_lambda = lambda;
  return o;
}

}  // namespace phasecast::server::tools
