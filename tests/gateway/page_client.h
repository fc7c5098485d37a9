#pragma once
// What a browser page does over the gateway's WebSocket, in C++ for tests:
// a Boost.Beast WebSocket client that sends PageMessages and reads PageEvents
// with timeouts, and a phasecast-gateway child process on loopback.

#include "listening_process.h"
#include "phasecast/proto/phasecast.pb.h"

#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core/flat_buffer.hpp>
#include <boost/beast/websocket.hpp>

#include <chrono>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace phasecast::testing {

class PageClient {
 public:
  // `receive_buffer` > 0: SO_RCVBUF of the socket, set before connecting (a
  // page whose socket fills quickly when it stops reading).
  PageClient(const std::string& host, unsigned short port, int receive_buffer = 0);
  ~PageClient();

  void send(const v1::PageMessage& message);
  void send_raw(const std::string& bytes, bool text = false);
  // The next event, or nothing within `timeout` (the connection is then
  // unusable) or when the gateway closed it (close_code() says why).
  std::optional<v1::PageEvent> next(std::chrono::milliseconds timeout = std::chrono::seconds(10));
  // Sends a request with a fresh id and returns its reply, passing the frames
  // that come before it to `on_frame` (or skipping them).
  v1::Reply call(v1::Request request, const std::function<void(const v1::Frame&)>& on_frame = {});
  void subscribe(const std::vector<std::uint32_t>& instances);
  std::optional<int> close_code() const { return close_code_; }
  const std::string& last_error() const { return last_error_; }

 private:
  boost::asio::io_context io_;
  boost::beast::websocket::stream<boost::asio::ip::tcp::socket> ws_;
  boost::beast::flat_buffer buffer_;
  std::optional<int> close_code_;
  std::string last_error_;
  std::uint64_t next_id_ = 1;
};

// phasecast-gateway --connect <server> --listen 127.0.0.1:0 <args>.
class GatewayProcess {
 public:
  GatewayProcess(const std::string& server_cmd, const std::vector<std::string>& args = {});
  unsigned short port() const { return port_; }
  std::string url() const { return "http://127.0.0.1:" + std::to_string(port_) + "/"; }
  int stop(int signal = 15) { return process_.stop(signal); }
  std::string err() { return process_.err(); }

 private:
  unsigned short port_ = 0;  // before process_: its constructor fills it
  ListeningProcess process_;
};

// GET of `target` from the gateway's HTTP side: status and body.
struct HttpResult {
  int status = 0;
  std::string body, content_type;
  std::string content_length;
};
// `headers`: extra request headers; `head`: a HEAD request instead of GET.
HttpResult http_get(unsigned short port, const std::string& target,
                    const std::vector<std::pair<std::string, std::string>>& headers = {}, bool head = false);

}  // namespace phasecast::testing
