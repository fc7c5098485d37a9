// phasecast-server: loads scene packages and streams synthesized (q_u, q_a)
// frames over ZeroMQ (paper §5, docs/protocol.md). With --replay-check it
// instead verifies that a recording replays bit for bit.

#include "phasecast/server/recording.h"
#include "phasecast/server/server.h"
#include "server_flags.h"

#include <fmt/format.h>
#include "phasecast/core/command_line.h"

#include <CLI/CLI.hpp>

#include <sys/resource.h>

#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstring>
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

// Every client connection is a descriptor: the soft limit (often 1024, or
// lower in containers) goes up to the hard limit, capped where the hard
// limit is unlimited by what the kernel allows (fs/nr_open), and the line
// says what happened.
void raise_descriptor_limit() {
  rlimit limit{};
  if (getrlimit(RLIMIT_NOFILE, &limit) != 0 || limit.rlim_cur >= limit.rlim_max) return;
  const rlim_t before = limit.rlim_cur;
  rlim_t wanted = limit.rlim_max;
  if (wanted == RLIM_INFINITY) {
    unsigned long long nr_open = 1u << 20;
    if (std::FILE* f = std::fopen("/proc/sys/fs/nr_open", "r")) {
      if (std::fscanf(f, "%llu", &nr_open) != 1) nr_open = 1u << 20;
      std::fclose(f);
    }
    wanted = static_cast<rlim_t>(nr_open);
  }
  limit.rlim_cur = wanted;
  if (setrlimit(RLIMIT_NOFILE, &limit) == 0) {
    fmt::print("phasecast-server: descriptor limit raised from {} to {}\n", before, wanted);
  } else {
    fmt::print("phasecast-server: descriptor limit stays {} (raising it to {} failed: {})\n", before, wanted,
               std::strerror(errno));
  }
}

// Runs the tick thread; the main thread waits for SIGINT/SIGTERM (blocked in
// every thread, so none is interrupted mid-tick) or for the tick thread to fail.
int serve(const ServerOptions& o) {
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  raise_descriptor_limit();
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
  phasecast::server::tools::ServerFlags flags;
  add_server_options(app, flags);
  if (const auto status = phasecast::core::parse_command_line(app, argc, argv, "phasecast-server"))
    return *status;
  const ServerOptions o = flags.resolved();
  try {
    return flags.replay.empty() ? serve(o) : replay_check(o, flags.replay);
  } catch (const std::exception& e) {
    fmt::print(stderr, "phasecast-server: {}\n", e.what());
    return 1;
  }
}
