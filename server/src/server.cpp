#include "phasecast/server/server.h"

#include <fmt/format.h>
#include <zmq.hpp>
#include <zmq_addon.hpp>

#include <chrono>
#include <cstdio>
#include <iterator>
#include <stdexcept>

namespace phasecast::server {
namespace {

using Clock = std::chrono::steady_clock;

constexpr auto kMaxPollWait = std::chrono::milliseconds(50);  // how soon a stop request is noticed
constexpr auto kResyncAfter = std::chrono::seconds(1);  // a stall longer than this restarts the schedule

std::string bind(zmq::socket_t& s, const std::string& endpoint, const char* option) {
  try {
    s.bind(endpoint);
  } catch (const zmq::error_t& e) {
    throw std::runtime_error(fmt::format("cannot bind {} '{}': {}", option, endpoint, e.what()));
  }
  return s.get(zmq::sockopt::last_endpoint);
}

}  // namespace

struct Server::Impl {
  explicit Impl(const ServerOptions& o)
      : service(o.rate_hz), router(context, zmq::socket_type::router), pub(context, zmq::socket_type::pub) {
    if (!(o.rate_hz > 0 && o.rate_hz <= 10000)) {
      throw std::runtime_error(fmt::format("--rate {} (expected a tick rate in (0, 10000] Hz)", o.rate_hz));
    }
    if (o.packages.empty()) throw std::runtime_error("no package given (expected at least one package.h5)");
    for (const auto& p : o.packages) service.load_package(p, o.blend_lambda);
    for (const auto& s : service.engine().scenes()) {
      for (int i = 0; i < o.instances_per_scene; ++i) service.engine().create_instance(s.name);
    }
    service.set_record_dir(o.record_dir);
    service.set_max_instances(o.max_instances);
    period = std::chrono::duration<double>(1.0 / o.rate_hz);

    router.set(zmq::sockopt::maxmsgsize, std::int64_t{kMaxRequestBytes});
    router.set(zmq::sockopt::sndhwm, 1000);
    router.set(zmq::sockopt::rcvhwm, 1000);
    router.set(zmq::sockopt::linger, 200);
    pub.set(zmq::sockopt::sndhwm, o.pub_high_water_mark);
    pub.set(zmq::sockopt::linger, 0);
    cmd_endpoint = bind(router, o.cmd_endpoint, "--cmd");
    pub_endpoint = bind(pub, o.pub_endpoint, "--pub");
    service.set_pub_endpoint(o.advertised_pub_endpoint.empty() ? pub_endpoint : o.advertised_pub_endpoint);
    if (o.record) service.start_recording(*o.record);
  }

  // Serves one queued request if there is one; returns whether there was.
  bool serve_one() {
    std::vector<zmq::message_t> parts;
    if (!zmq::recv_multipart(router, std::back_inserter(parts), zmq::recv_flags::dontwait)) return false;
    if (parts.size() != 3 || parts[1].size() != 0) {  // no [identity][""][Request] envelope: drop
      ++service.stats().requests;
      ++service.stats().bad_requests;
      return true;
    }
    const v1::Reply reply = service.handle(std::string_view(parts[2].data<char>(), parts[2].size()));
    std::array<zmq::message_t, 3> out{std::move(parts[0]), zmq::message_t(),
                                      zmq::message_t(reply.SerializeAsString())};
    try {
      zmq::send_multipart(router, out, zmq::send_flags::dontwait);  // a peer at its HWM loses the reply
    } catch (const zmq::error_t&) {
      // The peer vanished between request and reply; nothing to tell it.
    }
    return true;
  }

  void tick(Clock::time_point deadline) {
    const auto start = Clock::now();
    if (start - deadline > period / 4) ++service.stats().late_ticks;
    for (const auto& f : service.tick(start)) {
      // PUB never blocks: a subscriber past its high-water mark loses this frame.
      pub.send(zmq::buffer(f.topic), zmq::send_flags::sndmore | zmq::send_flags::dontwait);
      pub.send(zmq::buffer(f.payload), zmq::send_flags::dontwait);
    }
    if (service.recording_error() != reported_recording_error) {
      reported_recording_error = service.recording_error();
      fmt::print(stderr, "phasecast-server: recording stopped: {}\n", reported_recording_error);
    }
    const double took = std::chrono::duration<double>(Clock::now() - start).count();
    service.stats().max_tick_seconds = std::max(service.stats().max_tick_seconds, took);
  }

  void run(const std::atomic<bool>& stop) {
    auto next = Clock::now();
    zmq::pollitem_t items[] = {{router.handle(), 0, ZMQ_POLLIN, 0}};
    while (!stop.load(std::memory_order_relaxed)) {
      const auto now = Clock::now();
      if (now >= next) {
        tick(next);
        next += std::chrono::duration_cast<Clock::duration>(period);
        if (Clock::now() - next > kResyncAfter) next = Clock::now();
        continue;
      }
      const auto wait = std::min(std::chrono::ceil<std::chrono::milliseconds>(next - now), kMaxPollWait);
      zmq::poll(items, 1, wait);
      if (items[0].revents & ZMQ_POLLIN) {
        for (int i = 0; i < kRequestsPerSlice && serve_one(); ++i) {
        }
      }
    }
    service.stop_recording();
  }

  SynthesisService service;
  zmq::context_t context{1};
  zmq::socket_t router;
  zmq::socket_t pub;
  std::string cmd_endpoint, pub_endpoint;
  std::chrono::duration<double> period{};
  std::string reported_recording_error;
};

Server::Server(const ServerOptions& options) : impl_(std::make_unique<Impl>(options)) {}
Server::~Server() = default;
const std::string& Server::cmd_endpoint() const {
  return impl_->cmd_endpoint;
}
const std::string& Server::pub_endpoint() const {
  return impl_->pub_endpoint;
}
SynthesisService& Server::service() {
  return impl_->service;
}
void Server::run(const std::atomic<bool>& stop) {
  impl_->run(stop);
}

}  // namespace phasecast::server
