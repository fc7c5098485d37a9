// Transport figures on loopback TCP: publish throughput with 1, 4 and 16
// subscribers, and impulse-to-first-affected-frame latency through a real
// Server ticking at 60 Hz with 1000 instances.

#include "bench_scene.h"
#include "phasecast/server/server.h"
#include "phasecast/server/synthesis_service.h"

#include <benchmark/benchmark.h>
#include <zmq.hpp>
#include <zmq_addon.hpp>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <iterator>
#include <thread>
#include <vector>

namespace phasecast::bench {
namespace {

using Clock = std::chrono::steady_clock;

// Frames per second one publisher pushes out while `subs` subscribers drain
// every message (100 instances per tick, the tick loop without its sleep).
void BM_PublishThroughput(benchmark::State& state) {
  const int subs = static_cast<int>(state.range(0));
  server::SynthesisService service(60);
  service.load_package(cloth_ranks_package_file());
  for (int i = 0; i < 100; ++i) service.engine().create_instance("plate");
  zmq::context_t ctx(2);
  zmq::socket_t pub(ctx, zmq::socket_type::pub);
  pub.set(zmq::sockopt::sndhwm, 1000);
  pub.set(zmq::sockopt::linger, 0);
  pub.bind("tcp://127.0.0.1:*");
  const std::string endpoint = pub.get(zmq::sockopt::last_endpoint);
  std::atomic<bool> stop{false};
  std::atomic<std::uint64_t> received{0};
  std::atomic<int> joined{0};
  std::vector<std::thread> threads;
  for (int s = 0; s < subs; ++s) {
    threads.emplace_back([&] {
      zmq::socket_t sub(ctx, zmq::socket_type::sub);
      sub.set(zmq::sockopt::subscribe, "");
      sub.set(zmq::sockopt::rcvtimeo, 50);
      sub.set(zmq::sockopt::linger, 0);
      sub.connect(endpoint);
      bool first = true;
      while (!stop) {
        std::vector<zmq::message_t> parts;
        if (!zmq::recv_multipart(sub, std::back_inserter(parts))) continue;
        if (first) ++joined, first = false;
        ++received;
      }
    });
  }
  auto publish = [&] {
    for (const auto& f : service.tick()) {
      pub.send(zmq::buffer(f.topic), zmq::send_flags::sndmore);
      pub.send(zmq::buffer(f.payload), zmq::send_flags::none);
    }
  };
  while (joined < subs) publish();  // the slow-joiner handshake
  received = 0;
  std::uint64_t sent = 0;
  const auto t0 = Clock::now();
  for (auto _ : state) {
    publish();
    sent += 100;
  }
  const double elapsed = std::chrono::duration<double>(Clock::now() - t0).count();
  const std::uint64_t delivered = received.load();  // by the end of publishing
  stop = true;
  for (auto& t : threads) t.join();
  state.counters["frames_sent_per_s"] =
      benchmark::Counter(static_cast<double>(sent), benchmark::Counter::kIsRate);
  // What the subscribers actually took in while the publisher ran (the rest
  // was dropped at the high-water mark: the publisher never waits).
  state.counters["frames_delivered_per_s_all_subs"] = static_cast<double>(delivered) / elapsed;
  state.counters["delivered_fraction"] = static_cast<double>(delivered) / (static_cast<double>(sent) * subs);
}
BENCHMARK(BM_PublishThroughput)->Arg(1)->Arg(4)->Arg(16)->Unit(benchmark::kMicrosecond)->UseRealTime();

double percentile(std::vector<double> v, double p) {
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(p * static_cast<double>(v.size() - 1))];
}

// Time from sending an impulse to receiving the first frame of the instance
// that carries it, through a real Server (60 Hz, 1000 instances) on loopback.
void BM_ImpulseLatency(benchmark::State& state) {
  server::ServerOptions o;
  o.packages = {cloth_ranks_package_file()};
  o.cmd_endpoint = "tcp://127.0.0.1:*";
  o.pub_endpoint = "tcp://127.0.0.1:*";
  o.rate_hz = 60;
  o.instances_per_scene = static_cast<int>(state.range(0));
  server::Server srv(o);
  std::atomic<bool> stop{false};
  std::thread loop([&] { srv.run(stop); });
  const std::uint32_t target = static_cast<std::uint32_t>(o.instances_per_scene);  // the last instance
  zmq::context_t ctx;
  zmq::socket_t dealer(ctx, zmq::socket_type::dealer);
  dealer.connect(srv.cmd_endpoint());
  zmq::socket_t sub(ctx, zmq::socket_type::sub);
  sub.set(zmq::sockopt::subscribe, "inst/" + std::to_string(target) + "/");
  sub.connect(srv.pub_endpoint());
  std::vector<zmq::message_t> parts;
  (void)zmq::recv_multipart(sub, std::back_inserter(parts));  // joined
  const auto& pal = srv.service().engine().scenes()[0].data->palette;
  int current = -1;  // the instance's palette entry as its frames show it
  std::vector<double> samples;
  std::uint64_t id = 0;
  v1::Frame f;
  for (auto _ : state) {
    int d = 0;
    for (int k = 0; k < pal.size(); ++k) {
      d = static_cast<int>((id + static_cast<std::uint64_t>(k)) % static_cast<std::uint64_t>(pal.size()));
      if (pal.allowed(current, d)) break;
    }
    // Spread the send times over the tick period (deterministically) so the
    // figure is not tied to the phase right after a frame arrived.
    state.PauseTiming();
    std::this_thread::sleep_for(std::chrono::microseconds((id * 7919) % 16667));
    state.ResumeTiming();
    v1::Request r;
    r.set_id(++id);
    r.mutable_impulse()->set_instance(target);
    r.mutable_impulse()->set_index(static_cast<std::uint32_t>(d));
    const auto start = Clock::now();
    std::array<zmq::const_buffer, 2> req{zmq::buffer(std::string_view()), zmq::buffer(r.SerializeAsString())};
    zmq::send_multipart(dealer, req);
    parts.clear();
    (void)zmq::recv_multipart(dealer, std::back_inserter(parts));
    v1::Reply reply;
    reply.ParseFromArray(parts[1].data(), static_cast<int>(parts[1].size()));
    std::uint64_t at = 0;
    if (reply.ok()) at = reply.impulse().at_frame();
    do {  // frames arrive in order; the impulse's frame is the first affected one
      parts.clear();
      (void)zmq::recv_multipart(sub, std::back_inserter(parts));
      f.ParseFromArray(parts[1].data(), static_cast<int>(parts[1].size()));
    } while (f.frame() < at);
    const double latency = std::chrono::duration<double>(Clock::now() - start).count();
    current = f.palette_index();
    state.SetIterationTime(latency);
    if (reply.ok()) samples.push_back(latency);  // a refusal (the door hit its range meanwhile) is retried
  }
  stop = true;
  loop.join();
  state.counters["median_ms"] = 1e3 * percentile(samples, 0.5);
  state.counters["p99_ms"] = 1e3 * percentile(samples, 0.99);
  state.counters["samples"] = static_cast<double>(samples.size());
  state.counters["late_ticks"] = static_cast<double>(srv.service().stats().late_ticks);
  state.counters["ticks"] = static_cast<double>(srv.service().stats().ticks);
}
BENCHMARK(BM_ImpulseLatency)->Arg(1000)->Iterations(120)->UseManualTime()->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace phasecast::bench
