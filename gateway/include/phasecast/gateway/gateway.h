#pragma once
// phasecast-gateway (docs/gateway.md): lets browser pages join a
// phasecast-server. One port serves the page's files over HTTP and, at /ws, a
// WebSocket per page over which the page sends requests and subscriptions and
// receives replies and the frames of its instances (PageMessage / PageEvent
// in proto/phasecast.proto). One event-loop thread serves every page; a slow
// or hostile page loses only its own frames or its own connection.

#include "phasecast/client/network.h"

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

namespace phasecast::gateway {

struct GatewayOptions {
  std::string server = "tcp://127.0.0.1:5555";  // the server's command endpoint
  std::string listen = "127.0.0.1:8080";        // HOST:PORT; port 0 picks a free one
  std::filesystem::path web_root;               // the page's files (web/build.mjs output)
  client::CurveClientKeys curve;                // to the server (docs/security.md)
  std::uint32_t max_pages = 256;                // WebSocket connections at once
  std::uint32_t max_message_bytes = 64 * 1024;  // a larger page message closes its connection (1009)
  std::uint32_t max_requests_in_flight = 4;     // per page; its further messages wait unread
  std::uint32_t frame_queue = 8;                // frames queued per page before the oldest is dropped
  std::uint32_t max_subscriptions = 64;         // instances one page may follow
  std::uint32_t page_send_buffer = 128 * 1024;  // SO_SNDBUF of a page's socket, bytes
  std::vector<std::string> allow_origins;       // pages of these origins may connect too ("*": any)
  double max_request_rate = 200;                // requests/s per page (bursts of one second's worth)
  double request_timeout_s = 5;                 // a request the server has not answered by then fails
  double connect_timeout_s = 5;                 // for the server's first answer at start
};

// Counters of the gateway, also served as JSON at GET /stats.
struct GatewayStats {
  std::uint64_t pages = 0;             // WebSocket connections open now
  std::uint64_t pages_total = 0;       // opened since start
  std::uint64_t pages_refused = 0;     // over --max-pages
  std::uint64_t frames_forwarded = 0;  // frame events queued for pages
  std::uint64_t frames_dropped = 0;    // dropped from slow pages' queues
  std::uint64_t requests_forwarded = 0;
  std::uint64_t requests_refused = 0;  // by the gateway (kind, rate)
  std::uint64_t requests_timed_out = 0;
  std::uint64_t bad_messages = 0;        // unreadable page messages (the page got an error event)
  std::uint64_t oversized_messages = 0;  // connections closed with 1009
  std::uint64_t bytes_sent = 0;          // WebSocket payload bytes written to pages
  std::uint64_t bytes_received = 0;
};

class Gateway {
 public:
  // Asks the server for its frame endpoint (failing with one line naming the
  // server when it does not answer), connects to it and binds the port.
  explicit Gateway(GatewayOptions options);
  ~Gateway();
  Gateway(const Gateway&) = delete;
  Gateway& operator=(const Gateway&) = delete;

  // http://HOST:PORT/ as bound (the actual port when 0 was asked for).
  std::string url() const;
  // Serves until stop() is called (from any thread) or SIGINT/SIGTERM.
  void run();
  void stop();
  GatewayStats stats() const;  // a snapshot; call between runs or from the loop

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace phasecast::gateway
