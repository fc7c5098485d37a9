// phasecast-gateway: lets browser pages join a phasecast-server over
// WebSocket and serves the page itself (docs/gateway.md).

#include "phasecast/gateway/gateway.h"
#include "phasecast/gateway/static_files.h"

#include "phasecast/client/curve_options.h"

#include <fmt/format.h>
#include "phasecast/core/command_line.h"

#include <CLI/CLI.hpp>

#include <cstdio>
#include <exception>

namespace {

using phasecast::gateway::GatewayOptions;

void add_options(CLI::App& app, GatewayOptions& o, std::string& web_root) {
  app.add_option("--connect", o.server, "command endpoint of phasecast-server")->capture_default_str();
  app.add_option("--listen", o.listen,
                 "HOST:PORT to serve the page and its WebSocket (/ws) on; port 0 picks one")
      ->capture_default_str();
  app.add_option(
      "--web-root", web_root,
      "the page's files (web/build.mjs output; default: web/ next to bin/, else share/phasecast/web)");
  app.add_option("--max-pages", o.max_pages, "WebSocket connections at once; more are refused (HTTP 503)")
      ->check(CLI::Range(1u, 100000u))
      ->capture_default_str();
  app.add_option("--max-message-bytes", o.max_message_bytes,
                 "largest page message; a larger one closes that page's connection (code 1009)")
      ->check(CLI::Range(256u, 16u << 20))
      ->capture_default_str();
  app.add_option(
         "--max-requests-in-flight", o.max_requests_in_flight,
         "requests of one page at once, counted until their replies (and any error events) are written; "
         "its further messages wait unread")
      ->check(CLI::Range(1u, 1024u))
      ->capture_default_str();
  app.add_option("--frame-queue", o.frame_queue, "frames queued for a slow page before its oldest is dropped")
      ->check(CLI::Range(1u, 100000u))
      ->capture_default_str();
  app.add_option(
         "--page-send-buffer", o.page_send_buffer,
         "kernel send buffer per page, bytes: a slow page's older frames wait in the gateway's queue, "
         "where they can be dropped, not here")
      ->check(CLI::Range(4096u, 64u << 20))
      ->capture_default_str();
  app.add_option(
      "--allow-origin", o.allow_origins,
      "also accept pages served from this origin (e.g. https://example.org; * for any); by default "
      "only pages this gateway served may open its WebSocket");
  app.add_option("--max-request-rate", o.max_request_rate, "requests per second one page may send")
      ->check(CLI::Range(1.0, 1e6))
      ->capture_default_str();
  app.add_option("--request-timeout", o.request_timeout_s, "seconds before an unanswered request fails")
      ->check(CLI::Range(0.1, 3600.0))
      ->capture_default_str();
  app.add_option("--connect-timeout", o.connect_timeout_s,
                 "seconds to wait for the server's first answer at start")
      ->check(CLI::Range(0.1, 3600.0))
      ->capture_default_str();
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "phasecast-gateway: serves the Phasecast web page and forwards its WebSocket to a phasecast-server "
      "(requests, basis download, impulses, and the frames of the instances the page follows)."};
  GatewayOptions o;
  std::string web_root;
  phasecast::client::CurveKeyFiles keys;
  add_options(app, o, web_root);
  phasecast::client::add_curve_options(app, keys);
  if (const auto status = phasecast::core::parse_command_line(app, argc, argv, "phasecast-gateway"))
    return *status;
  try {
    o.web_root = web_root.empty() ? phasecast::gateway::default_web_root("/proc/self/exe")
                                  : std::filesystem::path(web_root);
    o.curve = phasecast::client::load_curve_client_keys(keys.server_key, keys.client_key);
    phasecast::gateway::Gateway gateway(o);
    if (!std::filesystem::exists(o.web_root / "index.html")) {
      fmt::print(stderr,
                 "phasecast-gateway: warning: no page in {} (build it with npm, or pass --web-root)\n",
                 o.web_root.string());
    }
    fmt::print("phasecast-gateway: serving {} (WebSocket at {}ws) for the server at {}\n", gateway.url(),
               gateway.url(), o.server);
    std::fflush(stdout);
    gateway.run();
    const auto s = gateway.stats();
    fmt::print("phasecast-gateway: stopped after {} pages, {} frames forwarded, {} dropped for slow pages\n",
               s.pages_total, s.frames_forwarded, s.frames_dropped);
    return 0;
  } catch (const std::exception& e) {
    fmt::print(stderr, "phasecast-gateway: {}\n", e.what());
    return 1;
  }
}
