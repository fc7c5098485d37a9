// phasecast-server: loads scene packages and streams synthesized (q_u, q_a)
// frames over ZeroMQ (paper §5, docs/protocol.md). With --replay-check it
// instead verifies that a recording replays bit for bit.

#include "phasecast/server/recording.h"
#include "phasecast/server/server.h"

#include <fmt/format.h>
#include "phasecast/core/command_line.h"

#include <CLI/CLI.hpp>

#include <csignal>
#include <cstdio>
#include <exception>
#include <thread>

namespace {

using phasecast::server::Server;
using phasecast::server::ServerOptions;

int replay_check(const ServerOptions& o, const std::string& recording) {
  phasecast::server::SynthesisService service(o.rate_hz);
  for (const auto& p : o.packages) service.load_package(p, o.blend_lambda);
  const auto entries = phasecast::core::read_recording_file(recording).entries;
  const auto r = phasecast::server::replay_check(service.engine(), entries);
  fmt::print(
      "phasecast-server: replay-check {}: {} frames of {} instances with {} impulses reproduced bit for "
      "bit\n",
      recording, r.frames, r.instances, r.impulses);
  return 0;
}

void announce(Server& server) {
  for (const auto& s : server.service().engine().scenes()) {
    const auto& p = *s.data;
    fmt::print(
        "phasecast-server: scene {} from {} (hash {:016x}): {} points, r_u = {}, r_a = {}, {} state nodes, "
        "{} "
        "IRFs, palette of {}\n",
        s.name, s.package, s.content_hash, p.mesh.points(), p.rank_u(), p.rank_a(), p.portrait.nodes(),
        p.portrait.irf_count(), p.palette.size());
  }
  for (const auto& [id, inst] : server.service().engine().instances()) {
    fmt::print("phasecast-server: instance {} of {} on topic inst/{}/\n", id,
               server.service().engine().scenes()[static_cast<std::size_t>(inst.scene)].name, id);
  }
  fmt::print("phasecast-server: listening cmd={} pub={}\n", server.cmd_endpoint(), server.pub_endpoint());
  std::fflush(stdout);
}

// Runs the tick thread; the main thread waits for SIGINT/SIGTERM (blocked in
// every thread, so none is interrupted mid-tick) or for the tick thread to fail.
int serve(const ServerOptions& o) {
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  Server server(o);
  announce(server);
  std::atomic<bool> stop{false}, done{false};
  std::exception_ptr failure;
  std::thread ticker([&] {
    try {
      server.run(stop);
    } catch (...) {
      failure = std::current_exception();
    }
    done = true;
  });
  const timespec poll_every{0, 100'000'000};
  while (!done && sigtimedwait(&signals, nullptr, &poll_every) < 0) {
  }
  stop = true;
  ticker.join();
  if (failure) std::rethrow_exception(failure);
  const auto st = server.service().stats();
  fmt::print(
      "phasecast-server: stopped after {} ticks, {} frames published, {} late ticks (longest tick {:.1f} "
      "ms), "
      "{} requests ({} bad, {} over a limit), {} handshakes refused\n",
      st.ticks, st.frames_published, st.late_ticks, st.max_tick_seconds * 1e3, st.requests, st.bad_requests,
      st.limited_requests, server.refused_handshakes());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Stream synthesized frames of precomputed deformable scenes over ZeroMQ (paper §5)."};
  ServerOptions o;
  std::vector<std::string> packages;
  std::string record, replay;
  double lambda = -1;
  app.add_option("packages", packages, "scene packages (.h5), one scene each")
      ->required()
      ->check(CLI::ExistingFile);
  app.add_option(
         "--cmd", o.cmd_endpoint,
         "ROUTER command endpoint to bind (loopback by default; tcp://*:5555 opens it to other hosts)")
      ->capture_default_str();
  app.add_option("--pub", o.pub_endpoint, "PUB frame endpoint to bind (loopback by default)")
      ->capture_default_str();
  app.add_option("--advertise-pub", o.advertised_pub_endpoint,
                 "frame endpoint clients are told to subscribe to (default: the bound --pub), e.g. "
                 "tcp://public-host:7556 behind NAT or remapped ports")
      ->check([](const std::string& e) {
        return e.rfind("tcp://", 0) == 0 || e.rfind("ipc://", 0) == 0 || e.rfind("inproc://", 0) == 0
                   ? std::string()
                   : "expected a ZeroMQ endpoint such as tcp://host:port, got '" + e + "'";
      });
  app.add_option("--rate", o.rate_hz, "tick rate, Hz")->check(CLI::Range(1e-3, 1e4))->capture_default_str();
  app.add_option("--instances", o.instances_per_scene, "instances created per scene at start")
      ->check(CLI::Range(0, 1000000))
      ->capture_default_str();
  app.add_option("--record", record, "record the published stream to this file from the start");
  app.add_option("--record-dir", o.record_dir,
                 "directory for recordings started by record_start requests (created on first use; give it a "
                 "folder of its own: clients name files in it)")
      ->capture_default_str();
  app.add_option("--record-max-bytes", o.limits.record_max_bytes,
                 "a recording ends (with a reason, the stream goes on) before it passes this size")
      ->check(CLI::Range(std::uint64_t{1} << 20, ~std::uint64_t{0}))
      ->capture_default_str();
  app.add_option("--blend-lambda", lambda, "override the packages' eq. 12 blend rate lambda, 1/s")
      ->check(CLI::Range(0.0, 1e9));
  app.add_option("--hwm", o.pub_high_water_mark, "frames queued per subscriber before it loses frames")
      ->check(CLI::Range(1, 10000000))
      ->capture_default_str();
  app.add_option("--max-instances", o.limits.max_instances,
                 "create_instance requests beyond this many instances in all are refused")
      ->check(CLI::Range(1, 1000000))
      ->capture_default_str();
  app.add_option("--max-instances-per-client", o.limits.max_instances_per_client,
                 "instances one client (CURVE key, else connection) may have created and not destroyed")
      ->check(CLI::Range(1, 1000000))
      ->capture_default_str();
  app.add_option("--impulse-horizon", o.limits.impulse_horizon_s,
                 "how far ahead an impulse's at_frame may lie, seconds")
      ->check(CLI::Range(0.0, 1e7))
      ->capture_default_str();
  app.add_option("--max-request-rate", o.limits.max_request_rate,
                 "requests per second one client may send (bursts of one second's worth)")
      ->check(CLI::Range(1.0, 1e9))
      ->capture_default_str();
  app.add_option("--max-pending-reply-bytes", o.limits.max_pending_reply_bytes,
                 "reply bytes queued for all clients together (slow readers); basis chunks past it are "
                 "refused")
      ->check(CLI::Range(std::uint64_t{1} << 20, ~std::uint64_t{0}))
      ->capture_default_str();
  app.add_option("--max-pending-reply-bytes-per-client", o.limits.max_pending_reply_bytes_per_client,
                 "reply bytes queued for one client (CURVE key, else connection); its basis chunks past it "
                 "are refused")
      ->check(CLI::Range(std::uint64_t{1} << 20, ~std::uint64_t{0}))
      ->capture_default_str();
  std::string secret_key, allow_clients;
  app.add_option("--curve-secret-key", secret_key,
                 "this server's CURVE secret key file (NAME.key from phasecast-keygen): encrypts and "
                 "authenticates both sockets")
      ->check(CLI::ExistingFile);
  app.add_option("--allow-clients", allow_clients,
                 "file of client public keys (NAME.pub lines) let in; others get nothing (needs "
                 "--curve-secret-key)")
      ->check(CLI::ExistingFile);
  app.add_option("--replay-check", replay, "verify that this recording replays bit for bit, then exit")
      ->check(CLI::ExistingFile);
  if (const auto status = phasecast::core::parse_command_line(app, argc, argv, "phasecast-server"))
    return *status;
  for (const auto& p : packages) o.packages.emplace_back(p);
  if (!secret_key.empty()) o.curve_secret_key = secret_key;
  if (!allow_clients.empty()) o.allow_clients = allow_clients;
  if (!record.empty()) o.record = record;
  if (lambda >= 0) o.blend_lambda = lambda;
  try {
    return replay.empty() ? serve(o) : replay_check(o, replay);
  } catch (const std::exception& e) {
    fmt::print(stderr, "phasecast-server: {}\n", e.what());
    return 1;
  }
}
