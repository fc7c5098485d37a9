// phasecast-bench-server-load: holds a real phasecast-server process under
// the load of issue 18 and reports whether it keeps its tick:
//   - `--subscribers` SUB sockets on every instance, drained by one thread,
//   - one subscriber that never reads (stalled: its ZeroMQ reads no further ahead),
//   - `--downloaders` clients downloading every basis part back to back,
//   - `--unread-clients` stalled clients, each sending `--unread` basis requests,
//   - the server recording the stream,
//   - a prober timing a stats request every 10 ms (command reply latency;
//     --probe scenes times list_scenes instead, which stays small however
//     many instances there are: a stats reply lists every one).
// At the end it reads the server's stats: late ticks, the longest tick, and
// its peak resident memory (VmHWM). Figures go to docs/performance-server.md.

#include "bench_scene.h"
#include "phasecast/core/process_memory.h"

#include <fmt/format.h>
#include "phasecast/core/command_line.h"

#include <CLI/CLI.hpp>
#include <zmq.hpp>
#include <zmq_addon.hpp>

#include "phasecast/proto/phasecast.pb.h"

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <thread>
#include <vector>

namespace {

using Clock = std::chrono::steady_clock;
using namespace std::chrono_literals;
namespace v1 = phasecast::v1;

struct Options {
  std::string server = "phasecast-server";
  std::string package;
  double rate = 60;
  int instances = 4;
  int subscribers = 1000;
  int downloaders = 2;
  int unread = 200;
  int unread_clients = 4;
  double seconds = 20;
  std::vector<std::string> server_args;  // passed on, e.g. --max-pending-reply-bytes
  bool baseline = false;                 // the server predates the limit options (a build of an older commit)
  bool record = true;                    // the server records the stream (--record on|off)
  double probe_every_ms = 10;            // between the prober's requests
  std::string probe = "stats";           // what the prober asks: stats or scenes (list_scenes)
  std::string topic = "inst/";           // what the subscribers (and the one never reading) subscribe to
};

// The server as a child process on free loopback ports.
struct ServerChild {
  pid_t pid = -1;
  std::string cmd, pub;
  std::filesystem::path dir;

  explicit ServerChild(const Options& o) {
    dir = std::filesystem::temp_directory_path() / fmt::format("phasecast_load_{}", ::getpid());
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    const auto log = dir / "server.log";
    pid = ::fork();
    if (pid == 0) {
      const auto rec = (dir / "load.phcrec").string();
      const auto inst = std::to_string(o.instances), rate = fmt::format("{}", o.rate);
      std::freopen(log.c_str(), "w", stdout);
      std::freopen((dir / "server.err").c_str(), "w",
                   stderr);  // not the bench's pipe: it would outlive the bench
      std::vector<std::string> args{o.server, o.package, "--instances",       inst,    "--rate",
                                    rate,     "--cmd",   "tcp://127.0.0.1:*", "--pub", "tcp://127.0.0.1:*"};
      if (o.record) args.insert(args.end(), {"--record", rec});
      // The prober and the downloaders go faster than the default request rate allows.
      if (!o.baseline) args.insert(args.end(), {"--max-request-rate", "100000"});
      args.insert(args.end(), o.server_args.begin(), o.server_args.end());
      std::vector<char*> argv;
      for (auto& a : args) argv.push_back(a.data());
      argv.push_back(nullptr);
      execv(o.server.c_str(), argv.data());
      _exit(127);
    }
    for (int i = 0; i < 600 && cmd.empty(); ++i) {
      std::this_thread::sleep_for(50ms);
      std::ifstream in(log);
      std::string line;
      while (std::getline(in, line)) {
        if (const auto at = line.find("listening cmd="); at != std::string::npos) {
          std::istringstream words(line.substr(at));
          std::string w;
          while (words >> w) {
            if (w.rfind("cmd=", 0) == 0) cmd = w.substr(4);
            if (w.rfind("pub=", 0) == 0) pub = w.substr(4);
          }
        }
      }
    }
    if (cmd.empty()) throw std::runtime_error("the server did not start (log " + log.string() + ")");
  }
  ~ServerChild() {
    ::kill(pid, SIGTERM);
    int status = 0;
    ::waitpid(pid, &status, 0);
    std::filesystem::remove_all(dir);
  }
  // Peak and current resident memory of the server, MiB.
  std::pair<double, double> memory_mib() const {
    const phasecast::core::ResidentMemory m = phasecast::core::resident_memory(pid);
    return {m.peak_mib, m.current_mib};
  }
};

v1::Reply call(zmq::socket_t& s, const v1::Request& r) {
  const std::string bytes = r.SerializeAsString();
  std::array<zmq::const_buffer, 2> out{zmq::buffer(std::string_view()), zmq::buffer(bytes)};
  zmq::send_multipart(s, out);
  std::vector<zmq::message_t> in;
  if (!zmq::recv_multipart(s, std::back_inserter(in)) || in.size() != 2) throw std::runtime_error("no reply");
  v1::Reply reply;
  reply.ParseFromArray(in[1].data(), static_cast<int>(in[1].size()));
  return reply;
}

// A peer that has stopped reading, as a hung process would: without this its
// ZeroMQ I/O thread keeps reading ahead (up to rcvhwm = 1000 messages) into
// the client's memory, and the server's queues never fill.
void stall(zmq::socket_t& s) {
  s.set(zmq::sockopt::rcvhwm, 1);
  s.set(zmq::sockopt::rcvbuf, 4096);
  s.set(zmq::sockopt::linger, 0);
}

zmq::socket_t dealer(zmq::context_t& ctx, const std::string& endpoint) {
  zmq::socket_t s(ctx, zmq::socket_type::dealer);
  s.set(zmq::sockopt::linger, 0);
  s.set(zmq::sockopt::rcvtimeo, 10000);
  s.connect(endpoint);
  return s;
}

v1::Request stats_request() {
  v1::Request r;
  r.mutable_stats();
  return r;
}

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<std::size_t>(p * static_cast<double>(v.size())))];
}

int run(const Options& o) {
  ServerChild server(o);
  zmq::context_t ctx(2);
  std::atomic<bool> stop{false};
  std::atomic<std::uint64_t> frames{0}, basis_bytes{0}, download_failures{0}, download_refusals{0};
  auto control = dealer(ctx, server.cmd);
  v1::Request list;
  list.mutable_list_scenes();
  const auto scene = call(control, list).scenes().scenes(0);

  const auto started = Clock::now();
  std::vector<std::thread> threads;
  threads.emplace_back([&] {  // every subscriber, drained by one poller
    std::vector<zmq::socket_t> subs;
    for (int i = 0; i < o.subscribers; ++i) {
      subs.emplace_back(ctx, zmq::socket_type::sub);
      subs.back().set(zmq::sockopt::subscribe, o.topic);
      subs.back().set(zmq::sockopt::linger, 0);
      subs.back().connect(server.pub);
    }
    std::vector<zmq::pollitem_t> items;
    for (auto& s : subs) items.push_back({s.handle(), 0, ZMQ_POLLIN, 0});
    while (!stop) {
      zmq::poll(items, 50ms);
      for (std::size_t i = 0; i < subs.size(); ++i) {
        if (!(items[i].revents & ZMQ_POLLIN)) continue;
        std::vector<zmq::message_t> parts;
        while (zmq::recv_multipart(subs[i], std::back_inserter(parts), zmq::recv_flags::dontwait)) {
          ++frames;
          parts.clear();
        }
      }
    }
  });
  zmq::socket_t sleeper(ctx, zmq::socket_type::sub);  // subscribes and never reads
  sleeper.set(zmq::sockopt::subscribe, o.topic);
  stall(sleeper);
  sleeper.connect(server.pub);
  for (int d = 0; d < o.downloaders; ++d) {
    threads.emplace_back([&] {
      auto s = dealer(ctx, server.cmd);
      while (!stop) try {
          for (const auto& part : scene.parts()) {
            for (std::uint64_t off = 0; off < part.total_bytes() && !stop;) {
              v1::Request r;
              r.mutable_basis()->set_scene(scene.name());
              r.mutable_basis()->set_part(part.part());
              r.mutable_basis()->set_offset(off);
              r.mutable_basis()->set_max_bytes(4u << 20);
              const auto reply = call(s, r);
              if (!reply.ok()) {  // over --max-pending-reply-bytes: start the part again later
                ++download_refusals;
                std::this_thread::sleep_for(10ms);
                break;
              }
              off += reply.basis().data().size();
              basis_bytes += reply.basis().data().size();
              if (reply.basis().data().empty()) break;
            }
          }
        } catch (const std::exception& e) {
          fmt::print(stderr, "download: {} at {:.1f} s\n", e.what(),
                     std::chrono::duration<double>(Clock::now() - started).count());
          ++download_failures;
          s = dealer(ctx, server.cmd);  // a fresh socket, as a client's retry would
        }
    });
  }
  std::vector<zmq::socket_t> hostile;  // ask for large replies and never read them
  for (int c = 0; c < o.unread_clients; ++c) {
    auto& h = hostile.emplace_back(ctx, zmq::socket_type::dealer);
    stall(h);
    h.connect(server.cmd);
    for (int i = 0; i < o.unread; ++i) {
      v1::Request r;
      r.mutable_basis()->set_scene(scene.name());
      r.mutable_basis()->set_part(v1::U_U);
      r.mutable_basis()->set_max_bytes(4u << 20);
      const std::string bytes = r.SerializeAsString();
      std::array<zmq::const_buffer, 2> out{zmq::buffer(std::string_view()), zmq::buffer(bytes)};
      zmq::send_multipart(h, out);
    }
  }

  std::vector<double> latencies;
  std::uint64_t peak_pending = 0;
  int lost = 0;
  const auto until = Clock::now() + std::chrono::duration<double>(o.seconds);
  while (Clock::now() < until) {
    const auto t0 = Clock::now();
    try {
      const auto probe = call(control, o.probe == "stats" ? stats_request() : list);
      peak_pending = std::max(peak_pending, probe.stats().pending_reply_bytes());
      latencies.push_back(std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
    } catch (const std::exception&) {
      ++lost;  // no reply within 10 s
      control = dealer(ctx, server.cmd);
    }
    std::this_thread::sleep_for(std::chrono::duration<double, std::milli>(o.probe_every_ms));
  }
  const auto stats = call(control, stats_request()).stats();
  const auto [hwm, rss] = server.memory_mib();
  stop = true;
  for (auto& t : threads) t.join();

  fmt::print(
      "load: {} Hz, {} instances, {} subscribers + 1 never reading, {} downloaders ({:.0f} MiB of bases), "
      "{} stalled clients x {} unread basis requests, recording {}, {:.0f} s\n",
      o.rate, o.instances, o.subscribers, o.downloaders, static_cast<double>(basis_bytes) / (1 << 20),
      o.unread_clients, o.unread, stats.recording() ? "on" : "OFF", o.seconds);
  fmt::print("ticks {}, late {} ({:.2f} %), longest tick {:.2f} ms\n", stats.ticks(), stats.late_ticks(),
             100.0 * static_cast<double>(stats.late_ticks()) /
                 static_cast<double>(std::max<std::uint64_t>(1, stats.ticks())),
             stats.max_tick_seconds() * 1e3);
  fmt::print(
      "command replies: {} probes, p50 {:.2f} ms, p99 {:.2f} ms, max {:.2f} ms, {} without a reply in 10 s; "
      "{} downloads without a reply in 10 s, {} basis requests refused\n",
      latencies.size(), percentile(latencies, 0.5), percentile(latencies, 0.99), percentile(latencies, 1.0),
      lost, download_failures.load(), download_refusals.load());
  const auto published = stats.frames_published() + stats.batches_published();
  fmt::print(
      "messages received by the subscribers: {} of {} published ({} frames, {} batches) x {} ({:.1f} %)\n",
      frames.load(), published, stats.frames_published(), stats.batches_published(), o.subscribers,
      100.0 * static_cast<double>(frames) /
          static_cast<double>(
              std::max<std::uint64_t>(1, published * static_cast<std::uint64_t>(o.subscribers))));
  fmt::print(
      "server memory: peak {:.0f} MiB, now {:.0f} MiB; reply bytes queued for clients: peak {:.1f} MiB; "
      "recording error: '{}'\n",
      hwm, rss, static_cast<double>(peak_pending) / (1 << 20), stats.recording_error());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "Hold a real phasecast-server under subscriber, download, hostile and recording load (issue 18)."};
  Options o;
  app.add_option("--server", o.server, "path of phasecast-server")->required();
  app.add_option("--package", o.package, "package to serve (default: the cloth-ranks bench scene)");
  app.add_option("--rate", o.rate, "tick rate, Hz")->capture_default_str();
  app.add_option("--instances", o.instances, "instances")->capture_default_str();
  app.add_option("--subscribers", o.subscribers, "subscribers on every instance")->capture_default_str();
  app.add_option("--downloaders", o.downloaders, "clients downloading bases back to back")
      ->capture_default_str();
  app.add_option("--unread", o.unread, "basis requests whose replies are never read, per stalled client")
      ->capture_default_str();
  app.add_option("--unread-clients", o.unread_clients, "stalled clients sending --unread basis requests each")
      ->capture_default_str();
  app.add_option("--seconds", o.seconds, "duration")->capture_default_str();
  app.add_option("--server-arg", o.server_args, "an argument passed on to the server (repeat for more)")
      ->allow_extra_args(false);
  std::string record = "on";
  app.add_option("--record", record, "on|off: the server records the stream")
      ->check(CLI::IsMember({"on", "off"}))
      ->capture_default_str();
  app.add_option("--probe", o.probe, "the prober's request: stats (lists every instance) or scenes")
      ->check(CLI::IsMember({"stats", "scenes"}))
      ->capture_default_str();
  app.add_option("--probe-every", o.probe_every_ms, "milliseconds between the prober's requests")
      ->capture_default_str();
  app.add_option("--topic", o.topic,
                 "what every subscriber subscribes to: inst/ (every instance's own frames) or "
                 "scene/NAME/ (the scene's batches)")
      ->capture_default_str();
  app.add_flag("--baseline", o.baseline, "the server is an older build without the limit options");
  if (const auto status = phasecast::core::parse_command_line(app, argc, argv, "phasecast-bench-server-load"))
    return *status;
  o.record = record == "on";
  if (o.package.empty()) o.package = phasecast::bench::cloth_ranks_package_file().string();
  try {
    return run(o);
  } catch (const std::exception& e) {
    fmt::print(stderr, "phasecast-bench-server-load: {}\n", e.what());
    return 1;
  }
}
