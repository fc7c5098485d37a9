#include "page_client.h"

#include "run_tool.h"

#include <boost/asio/connect.hpp>
#include <boost/beast/http.hpp>

#include <stdexcept>

namespace phasecast::testing {
namespace {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
using tcp = asio::ip::tcp;

// "phasecast-gateway: serving http://127.0.0.1:PORT/ ..." -> PORT.
bool parse_serving(const std::string& out, unsigned short& port) {
  const std::string marker = "serving http://127.0.0.1:";
  const auto at = out.find(marker);
  if (at == std::string::npos || out.find('\n', at) == std::string::npos) return false;
  port = static_cast<unsigned short>(std::stoul(out.substr(at + marker.size())));
  return true;
}

std::vector<std::string> gateway_argv(const std::string& server, const std::vector<std::string>& args) {
  std::vector<std::string> argv{tool_path("phasecast-gateway").string(), "--connect", server, "--listen",
                                "127.0.0.1:0"};
  argv.insert(argv.end(), args.begin(), args.end());
  return argv;
}

}  // namespace

PageClient::PageClient(const std::string& host, unsigned short port, int receive_buffer) : ws_(io_) {
  const tcp::endpoint gateway(asio::ip::make_address(host), port);
  ws_.next_layer().open(gateway.protocol());
  if (receive_buffer > 0) ws_.next_layer().set_option(asio::socket_base::receive_buffer_size(receive_buffer));
  ws_.next_layer().connect(gateway);
  ws_.handshake(host + ":" + std::to_string(port), "/ws");
  ws_.binary(true);
}

PageClient::~PageClient() {
  beast::error_code ec;
  ws_.next_layer().close(ec);
}

void PageClient::send(const v1::PageMessage& message) {
  send_raw(message.SerializeAsString());
}

void PageClient::send_raw(const std::string& bytes, bool text) {
  ws_.text(text);
  ws_.write(asio::buffer(bytes));
  ws_.binary(true);
}

std::optional<v1::PageEvent> PageClient::next(std::chrono::milliseconds timeout) {
  bool done = false;
  beast::error_code error;
  buffer_.consume(buffer_.size());
  ws_.async_read(buffer_, [&](beast::error_code ec, std::size_t) {
    done = true;
    error = ec;
  });
  io_.restart();
  io_.run_for(timeout);
  if (!done) {
    ws_.next_layer().cancel();
    io_.restart();
    io_.run();
    return std::nullopt;
  }
  if (error) {
    // The close frame's code, also when the gateway's socket closed before
    // this side could answer it (a broken pipe then, not error::closed).
    if (ws_.reason().code != beast::websocket::close_code::none) close_code_ = ws_.reason().code;
    last_error_ = error.message();
    return std::nullopt;
  }
  v1::PageEvent event;
  const auto data = buffer_.data();
  if (!event.ParseFromArray(data.data(), static_cast<int>(data.size()))) {
    throw std::runtime_error("the gateway sent something that is not a PageEvent");
  }
  return event;
}

v1::Reply PageClient::call(v1::Request request, const std::function<void(const v1::Frame&)>& on_frame) {
  request.set_id(next_id_++);
  v1::PageMessage m;
  *m.mutable_request() = request;
  send(m);
  for (int i = 0; i < 10000; ++i) {
    const auto e = next();
    if (!e) throw std::runtime_error("no reply through the gateway");
    if (e->has_reply() && e->reply().id() == request.id()) return e->reply();
    if (e->has_frame() && on_frame) on_frame(e->frame());
  }
  throw std::runtime_error("the reply never came among the frames");
}

void PageClient::subscribe(const std::vector<std::uint32_t>& instances) {
  v1::PageMessage m;
  auto* subscribe = m.mutable_subscribe();  // set even when empty: "follow nothing"
  for (auto i : instances) subscribe->add_instances(i);
  send(m);
}

GatewayProcess::GatewayProcess(const std::string& server_cmd, const std::vector<std::string>& args)
    : process_(gateway_argv(server_cmd, args), {},
               [this](const std::string& out) { return parse_serving(out, port_); }) {}

HttpResult http_get(unsigned short port, const std::string& target,
                    const std::vector<std::pair<std::string, std::string>>& headers, bool head) {
  asio::io_context io;
  tcp::socket socket(io);
  tcp::resolver resolver(io);
  asio::connect(socket, resolver.resolve("127.0.0.1", std::to_string(port)));
  http::request<http::empty_body> req{head ? http::verb::head : http::verb::get, target, 11};
  req.set(http::field::host, "127.0.0.1:" + std::to_string(port));
  for (const auto& [name, value] : headers) req.set(name, value);
  http::write(socket, req);
  beast::flat_buffer buffer;
  http::response_parser<http::string_body> parser;
  parser.skip(head);  // a HEAD response announces a body it does not send
  http::read(socket, buffer, parser);
  const auto& res = parser.get();
  return {static_cast<int>(res.result_int()), res.body(), std::string(res[http::field::content_type]),
          std::string(res[http::field::content_length])};
}

}  // namespace phasecast::testing
