#include "phasecast/server/server.h"

#include "phasecast/core/curve_keys.h"
#include "phasecast/server/thread_priority.h"

#include <fmt/format.h>
#include <zmq.hpp>
#include <zmq_addon.hpp>

#include <array>
#include <chrono>
#include <cstdio>
#include <iterator>
#include <map>
#include <mutex>
#include <set>
#include <stdexcept>
#include <thread>

namespace phasecast::server {
namespace {

using Clock = std::chrono::steady_clock;

constexpr auto kMaxWait = std::chrono::milliseconds(50);  // how soon a stop request is noticed
constexpr auto kResyncAfter = std::chrono::seconds(1);    // a stall longer than this restarts the schedule
constexpr int kRequestsPerWake = 64;                      // requests served between checks of `stop`
constexpr const char* kZapEndpoint = "inproc://zeromq.zap.01";  // fixed by ZeroMQ's RFC 27

std::string bind(zmq::socket_t& s, const std::string& endpoint, const char* option) {
  try {
    s.bind(endpoint);
  } catch (const zmq::error_t& e) {
    throw std::runtime_error(fmt::format("cannot bind {} '{}': {}", option, endpoint, e.what()));
  }
  return s.get(zmq::sockopt::last_endpoint);
}

std::string z85(const zmq::message_t& key) {
  std::array<char, core::kZ85KeyLength + 1> text{};
  if (key.size() != 32 || !zmq_z85_encode(text.data(), key.data<std::uint8_t>(), key.size())) return {};
  return text.data();
}

// Who sent a request, for the per-client limits: the CURVE key the ZAP
// handler vouched for, else the connection's routing id.
std::string client_of(const zmq::message_t& routing_id, zmq::message_t& request) {
  // The C call: cppzmq's gets() throws where a message has no such property.
  const char* user = zmq_msg_gets(request.handle(), "User-Id");
  if (user && *user) return fmt::format("key:{}", user);
  return fmt::format("conn:{}", routing_id.to_string());
}

// Answers ZeroMQ authentication (RFC 27, ZAP) for both sockets: a CURVE
// client whose public key is on the allow-list gets in, with the key as its
// User-Id; every other one is refused and hears nothing.
class ZapHandler {
 public:
  ZapHandler(zmq::context_t& context, std::set<std::string> allowed)
      : socket_(context, zmq::socket_type::rep), allowed_(std::move(allowed)) {
    socket_.bind(kZapEndpoint);
  }

  void run(const std::atomic<bool>& stop) {
    zmq::pollitem_t items[] = {{socket_.handle(), 0, ZMQ_POLLIN, 0}};
    while (!stop.load(std::memory_order_relaxed)) {
      zmq::poll(items, 1, kMaxWait);
      if (items[0].revents & ZMQ_POLLIN) answer();
    }
  }

 private:
  void answer() {
    std::vector<zmq::message_t> f;
    if (!zmq::recv_multipart(socket_, std::back_inserter(f), zmq::recv_flags::dontwait)) return;
    // version, request id, domain, address, identity, mechanism, credentials...
    const bool curve = f.size() >= 7 && f[5].to_string_view() == "CURVE";
    const std::string key = curve ? z85(f[6]) : std::string();
    const bool ok = !key.empty() && allowed_.count(key) != 0;
    std::array<zmq::message_t, 6> reply{
        zmq::message_t(std::string_view("1.0")),
        f.size() > 1 ? std::move(f[1]) : zmq::message_t(),
        zmq::message_t(std::string_view(ok ? "200" : "400")),
        zmq::message_t(std::string_view(ok ? "OK" : "client key not allowed")),
        zmq::message_t(ok ? key : std::string()),
        zmq::message_t()};
    zmq::send_multipart(socket_, reply);
    if (!ok) ++refused;
  }

  zmq::socket_t socket_;
  std::set<std::string> allowed_;

 public:
  std::atomic<std::uint64_t> refused{0};
};

// Reply bytes handed to ZeroMQ and not yet freed by it (written to the
// connection, or dropped with it), in all and per client. Shared with the
// queued messages, which ZeroMQ's I/O thread may free as late as the
// context's end.
class PendingReplies {
 public:
  using Counter = std::shared_ptr<std::atomic<std::uint64_t>>;

  Counter of(const std::string& client) {
    std::lock_guard lock(mutex_);
    auto& c = by_client_[client];
    if (!c) c = std::make_shared<std::atomic<std::uint64_t>>(0);
    Counter found = c;
    if (by_client_.size() > kPruneAbove) prune();
    return found;
  }
  PendingReplyBytes count(const std::string& client) const {
    std::lock_guard lock(mutex_);
    const auto it = by_client_.find(client);
    return {all_, it == by_client_.end() ? 0 : it->second->load()};
  }
  std::atomic<std::uint64_t>& all() { return all_; }

 private:
  static constexpr std::size_t kPruneAbove = 4096;  // clients come and go; forget the idle ones
  void prune() {
    std::erase_if(by_client_,
                  [](const auto& e) { return e.second.use_count() == 1 && e.second->load() == 0; });
  }

  mutable std::mutex mutex_;
  std::map<std::string, Counter> by_client_;
  std::atomic<std::uint64_t> all_{0};
};

// A serialized reply handed to ZeroMQ without a copy, counted until freed.
struct QueuedReply {
  std::string bytes;
  std::shared_ptr<PendingReplies> pending;
  PendingReplies::Counter client;
};

zmq::message_t queued_reply(std::string bytes, const std::shared_ptr<PendingReplies>& pending,
                            const std::string& client) {
  auto* r = new QueuedReply{std::move(bytes), pending, pending->of(client)};
  r->pending->all() += r->bytes.size();
  *r->client += r->bytes.size();
  return zmq::message_t(
      r->bytes.data(), r->bytes.size(),
      [](void*, void* hint) {
        auto* done = static_cast<QueuedReply*>(hint);
        done->pending->all() -= done->bytes.size();
        *done->client -= done->bytes.size();
        delete done;
      },
      r);
}

}  // namespace

struct Server::Impl {
  explicit Impl(const ServerOptions& o)
      : service(o.rate_hz),
        packages_loaded(load_packages(service, o)),
        router(context, zmq::socket_type::router),
        pub(context, zmq::socket_type::xpub) {
    service.set_record_dir(o.record_dir);
    service.set_limits(o.limits);
    service.set_pending_reply_bytes(
        [pending = pending_replies](const std::string& client) { return pending->count(client); });
    period = std::chrono::duration<double>(1.0 / o.rate_hz);
    set_up_security(o);

    router.set(zmq::sockopt::maxmsgsize, std::int64_t{kMaxMessageBytes});
    // A client that does not read its replies holds at most this many (each
    // at most one basis chunk); past that ROUTER drops its replies. Not much
    // lower: ZeroMQ learns of reads in batches, and at 8 it dropped replies
    // of clients that read every one (bench/server/load_bench.cpp).
    router.set(zmq::sockopt::sndhwm, kReplyQueuePerClient);
    router.set(zmq::sockopt::router_mandatory, true);  // a full peer refuses the send: send_reply
    router.set(zmq::sockopt::rcvhwm, 1000);
    router.set(zmq::sockopt::linger, 200);
    pub.set(zmq::sockopt::sndhwm, o.pub_high_water_mark);
    pub.set(zmq::sockopt::linger, 0);
    const int handshake_ms = static_cast<int>(o.handshake_timeout_s * 1000);
    for (auto* s : {&router, &pub}) s->set(zmq::sockopt::handshake_ivl, handshake_ms);
    cmd_endpoint = bind(router, o.cmd_endpoint, "--cmd");
    pub_endpoint = bind(pub, o.pub_endpoint, "--pub");
    service.set_pub_endpoint(o.advertised_pub_endpoint.empty() ? pub_endpoint : o.advertised_pub_endpoint);
    if (o.record) service.start_recording(*o.record);
    service.set_subscriptions(subscribed);  // nobody yet: build no message until someone subscribes
  }

  // Checks the options the service needs, loads the packages and creates the
  // instances asked for at start.
  static bool load_packages(SynthesisService& service, const ServerOptions& o) {
    if (!(o.handshake_timeout_s >= 0.1 && o.handshake_timeout_s <= 3600)) {
      throw std::runtime_error(
          fmt::format("--handshake-timeout {} (expected seconds in [0.1, 3600])", o.handshake_timeout_s));
    }
    if (!(o.rate_hz > 0 && o.rate_hz <= 10000)) {
      throw std::runtime_error(fmt::format("--rate {} (expected a tick rate in (0, 10000] Hz)", o.rate_hz));
    }
    if (o.packages.empty()) throw std::runtime_error("no package given (expected at least one package.h5)");
    for (const auto& p : o.packages) service.load_package(p, o.blend_lambda);
    for (const auto& s : service.engine().scenes()) {
      for (int i = 0; i < o.instances_per_scene; ++i) service.engine().create_instance(s.name);
    }
    return true;
  }

  void set_up_security(const ServerOptions& o) {
    if (o.allow_clients && !o.curve_secret_key) {
      throw std::runtime_error(
          "--allow-clients needs --curve-secret-key (an allow-list works only with CURVE)");
    }
    if (!o.curve_secret_key) return;
    const auto keys = core::read_secret_key_file(*o.curve_secret_key);
    if (o.allow_clients) {
      const auto allowed = core::read_public_keys(*o.allow_clients);
      zap = std::make_unique<ZapHandler>(context, std::set<std::string>(allowed.begin(), allowed.end()));
    }
    for (auto* s : {&router, &pub}) {
      s->set(zmq::sockopt::curve_server, true);
      s->set(zmq::sockopt::curve_secretkey, keys.secret_z85);
      s->set(zmq::sockopt::zap_domain, "phasecast");
    }
  }

  // Serves one queued request if there is one; returns whether there was.
  bool serve_one() {
    std::vector<zmq::message_t> parts;
    if (!zmq::recv_multipart(router, std::back_inserter(parts), zmq::recv_flags::dontwait)) return false;
    if (parts.size() != 3 || parts[1].size() != 0) {  // no [identity][""][Request] envelope: drop
      service.count_bad_message();
      return true;
    }
    const std::string client = client_of(parts[0], parts[2]);
    v1::Reply reply;
    if (parts[2].size() > static_cast<std::size_t>(kMaxRequestBytes)) {
      service.count_bad_message();
      reply.set_ok(false);
      reply.set_error(fmt::format("request: {} bytes (expected at most {} bytes per request)",
                                  parts[2].size(), kMaxRequestBytes));
    } else {
      reply = service.handle(std::string_view(parts[2].data<char>(), parts[2].size()), client);
    }
    std::array<zmq::message_t, 3> out{std::move(parts[0]), zmq::message_t(),
                                      queued_reply(reply.SerializeAsString(), pending_replies, client)};
    send_reply(out);
    return true;
  }

  // A peer at its high-water mark loses the reply. ROUTER learns that a peer
  // read its replies only from acknowledgements waiting in its command queue:
  // under load a client that reads every reply could still look full (the
  // 65th or 97th of 100 sequential replies was lost in 9 runs of 400 beside
  // CPU hogs), so a refused send first has those processed and is tried again.
  void send_reply(std::array<zmq::message_t, 3>& out) {
    try {
      if (zmq::send_multipart(router, out, zmq::send_flags::dontwait)) return;  // ROUTER_MANDATORY: EAGAIN
      (void)router.get(zmq::sockopt::events);  // processes the acknowledgements waiting
      (void)zmq::send_multipart(router, out, zmq::send_flags::dontwait);
    } catch (const zmq::error_t&) {
      // The peer vanished between request and reply (EHOSTUNREACH); nothing to tell it.
    }
  }

  void serve_commands(const std::atomic<bool>& stop) {
    yield_to_the_tick();
    zmq::pollitem_t items[] = {{router.handle(), 0, ZMQ_POLLIN, 0}};
    while (!stop.load(std::memory_order_relaxed)) {
      zmq::poll(items, 1, kMaxWait);
      if (items[0].revents & ZMQ_POLLIN) {
        for (int i = 0; i < kRequestsPerWake && serve_one(); ++i) {
        }
      }
    }
  }

  // The tick's time runs from its deadline-checked start through synthesis
  // (including any wait for the service's lock) to the last frame handed to
  // ZeroMQ, so max_tick_seconds is what a subscriber feels.
  void tick(Clock::time_point deadline) {
    const auto start = Clock::now();
    read_subscriptions();
    for (const auto& f : service.tick()) {
      // PUB never blocks: a subscriber past its high-water mark loses this frame.
      pub.send(zmq::buffer(f.topic), zmq::send_flags::sndmore | zmq::send_flags::dontwait);
      pub.send(zmq::buffer(f.payload), zmq::send_flags::dontwait);
    }
    if (const auto error = service.recording_error(); error != reported_recording_error) {
      reported_recording_error = error;
      fmt::print(stderr, "phasecast-server: recording stopped: {}\n", error);
    }
    const double took = std::chrono::duration<double>(Clock::now() - start).count();
    service.count_tick(took, start - deadline > period / 4);
  }

  // XPUB hands up each topic prefix as '\1' + prefix when its first subscriber
  // comes and '\0' + prefix when its last one goes (ZeroMQ drops the repeats).
  void read_subscriptions() {
    bool changed = false;
    zmq::message_t m;
    while (pub.recv(m, zmq::recv_flags::dontwait)) {
      if (m.size() == 0) continue;
      const auto* bytes = m.data<char>();
      std::string prefix(bytes + 1, m.size() - 1);
      if (bytes[0] == 1) {
        changed |= subscribed.insert(std::move(prefix)).second;
      } else if (bytes[0] == 0) {
        changed |= subscribed.erase(prefix) > 0;
      }
    }
    if (changed) service.set_subscriptions(subscribed);
  }

  // Ticks until `stop` (the caller's) or `done` (a failed command thread).
  void run_ticks(const std::atomic<bool>& stop, const std::atomic<bool>& done) {
    auto next = Clock::now();
    while (!stop.load(std::memory_order_relaxed) && !done.load(std::memory_order_relaxed)) {
      const auto now = Clock::now();
      if (now < next) {
        std::this_thread::sleep_until(std::min(next, now + kMaxWait));
        continue;
      }
      tick(next);
      next += std::chrono::duration_cast<Clock::duration>(period);
      if (Clock::now() - next > kResyncAfter) next = Clock::now();
    }
  }

  void run(const std::atomic<bool>& stop) {
    std::atomic<bool> done{false};
    std::exception_ptr tick_failure, command_failure;
    std::thread zap_thread;
    if (zap) zap_thread = std::thread([&] { zap->run(done); });
    std::thread commands([&] {
      try {
        serve_commands(done);
      } catch (...) {
        command_failure = std::current_exception();
        done = true;  // a server that cannot answer stops rather than ticks on deaf
      }
    });
    try {
      run_ticks(stop, done);
    } catch (...) {
      tick_failure = std::current_exception();
    }
    done = true;
    commands.join();
    if (zap_thread.joinable()) zap_thread.join();
    service.stop_recording();
    for (const auto& failure : {tick_failure, command_failure})
      if (failure) std::rethrow_exception(failure);
  }

  SynthesisService service;
  // Before any socket exists: the package reader forks a probe child, which
  // is only safe while this process has no other threads (ZeroMQ's start with
  // the first socket; ASan's allocator deadlocked a child forked beside them).
  const bool packages_loaded;
  std::shared_ptr<PendingReplies> pending_replies = std::make_shared<PendingReplies>();
  zmq::context_t context{1};
  std::unique_ptr<ZapHandler> zap;  // before the sockets: ZeroMQ asks it during their handshakes
  zmq::socket_t router;
  zmq::socket_t pub;                 // XPUB: publishes and tells which topics are wanted
  std::set<std::string> subscribed;  // topic prefixes with at least one subscriber
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
std::uint64_t Server::refused_handshakes() const {
  return impl_->zap ? impl_->zap->refused.load() : 0;
}
void Server::run(const std::atomic<bool>& stop) {
  impl_->run(stop);
}

}  // namespace phasecast::server
