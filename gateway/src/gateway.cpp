#include "phasecast/gateway/gateway.h"

#include "phasecast/gateway/page_protocol.h"
#include "phasecast/gateway/server_link.h"
#include "phasecast/gateway/static_files.h"

#include <fmt/format.h>
#include <boost/asio/signal_set.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <nlohmann/json.hpp>

#include <chrono>
#include <stdexcept>
#include <unordered_map>
#include <unordered_set>
#include <vector>

namespace phasecast::gateway {
namespace {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
using tcp = asio::ip::tcp;
using Clock = std::chrono::steady_clock;

constexpr std::uint32_t kProtocolVersion = 1;
constexpr const char* kServerName = "phasecast-gateway";

tcp::endpoint parse_listen(const std::string& text) {
  const auto colon = text.rfind(':');
  const auto fail = [&](const std::string& why) {
    return std::invalid_argument(
        fmt::format("--listen '{}' is invalid ({}; expected HOST:PORT, e.g. 127.0.0.1:8080)", text, why));
  };
  if (colon == std::string::npos) throw fail("no port");
  boost::system::error_code ec;
  const auto address = asio::ip::make_address(text.substr(0, colon), ec);
  if (ec) throw fail("the host is not an IP address");
  unsigned long port = 0;
  try {
    std::size_t used = 0;
    port = std::stoul(text.substr(colon + 1), &used);
    if (used != text.size() - colon - 1) throw std::invalid_argument("");
  } catch (const std::exception&) {
    throw fail("the port is not a number");
  }
  if (port > 65535) throw fail("the port is over 65535");
  return {address, static_cast<unsigned short>(port)};
}

double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

class PageSession;

// One of the gateway's bounded connection slots, held by an HTTP connection
// and then by the page it became, given back when its holder goes. The count
// is shared so that holders destroyed after the Hub (at shutdown) are safe.
class ConnectionSlot {
 public:
  explicit ConnectionSlot(std::shared_ptr<std::uint32_t> count) : count_(std::move(count)) { ++*count_; }
  ConnectionSlot(ConnectionSlot&&) = default;
  ConnectionSlot& operator=(ConnectionSlot&&) = default;
  ConnectionSlot(const ConnectionSlot&) = delete;
  ConnectionSlot& operator=(const ConnectionSlot&) = delete;
  ~ConnectionSlot() {
    if (count_) --*count_;
  }

 private:
  std::shared_ptr<std::uint32_t> count_;
};

// Origin of a browser's upgrade request ("http://host:port") against the
// Host it was sent to: other sites' pages may not drive this gateway (a
// WebSocket is not bound by the same-origin rule) unless --allow-origin says.
bool origin_allowed(std::string_view origin, std::string_view host, const std::vector<std::string>& allowed) {
  if (origin.empty()) return true;  // not a browser
  for (const auto& a : allowed) {
    if (a == "*" || a == origin) return true;
  }
  const auto scheme = origin.find("://");
  return scheme != std::string_view::npos && origin.substr(scheme + 3) == host;
}

// What every page shares: the server link, the gateway's request ids, the
// subscriptions, the counters. Lives on the event-loop thread only.
class Hub {
 public:
  Hub(asio::io_context& loop, const GatewayOptions& options, std::string pub_endpoint);

  const GatewayOptions& options() const { return options_; }
  GatewayStats& stats() { return stats_; }
  double now() const { return seconds_since(start_); }
  v1::GatewayHello hello() const;

  // Pages counted with those still in their WebSocket handshake.
  bool admit() const { return pages_.size() + handshakes_ < options_.max_pages; }
  void opening_handshake() { ++handshakes_; }
  void opened_handshake() { --handshakes_; }
  // HTTP connections at once, pages included: beyond the bound a new
  // connection is closed at once, so file descriptors never run out.
  std::optional<ConnectionSlot> take_connection() {
    if (*connections_ >= 2 * options_.max_pages + 64) return std::nullopt;
    return ConnectionSlot(connections_);
  }
  // Registers an open page; returns its id.
  std::uint64_t add(const std::shared_ptr<PageSession>& page);
  nlohmann::json page_stats() const;
  void remove(PageSession* page);
  // Forwards a request of `page` under a gateway id; the reply goes back to it.
  void forward(const std::shared_ptr<PageSession>& page, v1::Request request);

 private:
  struct Pending {
    std::weak_ptr<PageSession> page;
    std::uint64_t page_id;
    double sent_at;
  };
  void on_reply(const std::string& bytes);
  void on_frame(std::uint32_t instance, const std::string& bytes);
  void expire_requests();
  void schedule_expiry();

  asio::io_context& loop_;
  GatewayOptions options_;
  Clock::time_point start_ = Clock::now();
  GatewayStats stats_;
  // Owns the open pages: a page waiting only for replies (no read or write
  // pending) has nothing else keeping it alive.
  std::unordered_map<PageSession*, std::shared_ptr<PageSession>> pages_;
  std::unordered_map<std::uint64_t, Pending> pending_;
  std::uint32_t handshakes_ = 0;
  std::shared_ptr<std::uint32_t> connections_ = std::make_shared<std::uint32_t>(0);
  std::uint64_t next_id_ = 1;
  asio::steady_timer expiry_{loop_};
  std::unique_ptr<ServerLink> link_;  // last: its thread posts into the loop until it is joined
};

// One page's WebSocket: reads PageMessages (one at a time, and none while it
// has max_requests_in_flight unanswered), writes its outbox.
class PageSession : public std::enable_shared_from_this<PageSession> {
 public:
  PageSession(tcp::socket socket, Hub& hub, ConnectionSlot slot)
      : slot_(std::move(slot)),
        ws_(std::move(socket)),
        hub_(hub),
        outbox_(hub.options().frame_queue),
        rate_(hub.options().max_request_rate, std::max(1.0, hub.options().max_request_rate)) {}

  void accept(http::request<http::string_body> upgrade) {
    ws_.set_option(websocket::stream_base::timeout::suggested(beast::role_type::server));
    ws_.set_option(websocket::stream_base::decorator(
        [](websocket::response_type& res) { res.set(http::field::server, kServerName); }));
    ws_.read_message_max(hub_.options().max_message_bytes);
    ws_.binary(true);
    ws_.async_accept(upgrade, [self = shared_from_this()](beast::error_code ec) {
      self->hub_.opened_handshake();
      if (ec) return;
      self->id_ = self->hub_.add(self);
      self->send(PageOutbox::Kind::notice, hello_event(self->hub_.hello()));
      self->read();
    });
  }

  bool follows(std::uint32_t instance) const { return subscribed_.contains(instance); }

  // Replies and notices are never dropped, so each counts against the page's
  // bound until written: a page that never reads stops being read.
  void send(PageOutbox::Kind kind, std::string bytes) {
    if (closed_) return;
    ++unwritten_;
    outbox_.push(kind, std::make_shared<const std::string>(std::move(bytes)));
    write();
  }

  void send_frame(const PageOutbox::Bytes& frame) {
    if (closed_) return;
    const auto before = outbox_.dropped_frames();
    outbox_.push(PageOutbox::Kind::frame, frame);
    hub_.stats().frames_dropped += outbox_.dropped_frames() - before;
    ++hub_.stats().frames_forwarded;
    write();
  }

  void answer_locally(std::uint64_t id, const std::string& error) {
    v1::Reply reply;
    reply.set_id(id);
    reply.set_ok(false);
    reply.set_error(error);
    send(PageOutbox::Kind::reply, reply_event(reply));
  }

  void reply_from_server(v1::Reply reply, std::uint64_t page_id) {
    --at_server_;
    reply.set_id(page_id);
    send(PageOutbox::Kind::reply, reply_event(reply));
  }

  std::uint64_t id() const { return id_; }
  std::uint64_t dropped_frames() const { return outbox_.dropped_frames(); }

 private:
  void read() {
    if (reading_ || closed_ || at_server_ + unwritten_ >= hub_.options().max_requests_in_flight) return;
    reading_ = true;
    ws_.async_read(buffer_, [self = shared_from_this()](beast::error_code ec, std::size_t bytes) {
      self->reading_ = false;
      if (ec) return self->end(ec);
      self->hub_.stats().bytes_received += bytes;
      self->on_message();
      self->buffer_.consume(self->buffer_.size());
      self->read();
    });
  }

  void on_message() {
    if (ws_.got_text()) {
      return refuse_message("a text message is not a PageMessage (expected a binary protobuf PageMessage)");
    }
    v1::PageMessage message;
    const auto data = buffer_.data();
    if (!message.ParseFromArray(data.data(), static_cast<int>(data.size()))) {
      return refuse_message(
          fmt::format("a message of {} bytes is not a PageMessage (expected a binary protobuf PageMessage)",
                      data.size()));
    }
    switch (message.body_case()) {
      case v1::PageMessage::kSubscribe:
        return subscribe(message.subscribe());
      case v1::PageMessage::kRequest:
        return request(std::move(*message.mutable_request()));
      case v1::PageMessage::BODY_NOT_SET:
        return refuse_message("a PageMessage has no body (expected request or subscribe)");
    }
  }

  void refuse_message(const std::string& why) {
    ++hub_.stats().bad_messages;
    send(PageOutbox::Kind::notice, error_event(why));
  }

  void subscribe(const v1::Subscribe& s) {
    if (static_cast<std::uint32_t>(s.instances_size()) > hub_.options().max_subscriptions) {
      return refuse_message(fmt::format("subscribe names {} instances (at most {} per page)",
                                        s.instances_size(), hub_.options().max_subscriptions));
    }
    subscribed_ = {s.instances().begin(), s.instances().end()};
  }

  void request(v1::Request r) {
    if (auto why = refusal(r); !why.empty()) {
      ++hub_.stats().requests_refused;
      return answer_locally(r.id(), why);
    }
    if (!rate_.take(hub_.now())) {
      ++hub_.stats().requests_refused;
      return answer_locally(r.id(),
                            fmt::format("{}: more than {:g} requests/s from this page (--max-request-rate)",
                                        request_kind(r), hub_.options().max_request_rate));
    }
    ++at_server_;
    hub_.forward(shared_from_this(), std::move(r));
  }

  void write() {
    if (closed_) return;
    const auto bytes = outbox_.start_write();
    if (!bytes) return;
    ws_.async_write(asio::buffer(*bytes),
                    [self = shared_from_this(), bytes](beast::error_code ec, std::size_t n) {
                      if (ec) return self->end(ec);
                      self->hub_.stats().bytes_sent += n;
                      if (self->outbox_.finish_write() != PageOutbox::Kind::frame) {
                        --self->unwritten_;
                        self->read();  // it may have been waiting for this
                      }
                      self->write();
                    });
  }

  void end(beast::error_code ec) {
    if (closed_) return;
    closed_ = true;
    if (ec == websocket::error::message_too_big) ++hub_.stats().oversized_messages;
    hub_.remove(this);
  }

  ConnectionSlot slot_;
  websocket::stream<beast::tcp_stream> ws_;
  Hub& hub_;
  beast::flat_buffer buffer_;
  PageOutbox outbox_;
  RequestRate rate_;
  std::unordered_set<std::uint32_t> subscribed_;
  std::uint64_t id_ = 0;         // 1, 2, ... in the order pages connected (/stats)
  std::uint32_t at_server_ = 0;  // requests forwarded, not answered yet
  std::uint32_t unwritten_ = 0;  // replies and notices queued, not written yet
  bool reading_ = false, closed_ = false;
};

Hub::Hub(asio::io_context& loop, const GatewayOptions& options, std::string pub_endpoint)
    : loop_(loop), options_(options) {
  ServerLinkOptions link{options.server, std::move(pub_endpoint), options.curve,
                         std::chrono::milliseconds(static_cast<long>(options.connect_timeout_s * 1000))};
  link_ = std::make_unique<ServerLink>(
      std::move(link),
      [this](std::string bytes) { asio::post(loop_, [this, b = std::move(bytes)] { on_reply(b); }); },
      [this](std::uint32_t instance, std::string bytes) {
        asio::post(loop_, [this, instance, b = std::move(bytes)] { on_frame(instance, b); });
      });
  schedule_expiry();
}

v1::GatewayHello Hub::hello() const {
  v1::GatewayHello h;
  h.set_protocol_version(kProtocolVersion);
  h.set_server(options_.server);
  h.set_max_message_bytes(options_.max_message_bytes);
  h.set_max_requests_in_flight(options_.max_requests_in_flight);
  h.set_frame_queue(options_.frame_queue);
  return h;
}

std::uint64_t Hub::add(const std::shared_ptr<PageSession>& page) {
  pages_[page.get()] = page;
  stats_.pages = pages_.size();
  return ++stats_.pages_total;
}

// Frames dropped per open page, by page id: which page was slow.
nlohmann::json Hub::page_stats() const {
  nlohmann::json pages = nlohmann::json::object();
  for (const auto& [raw, page] : pages_)
    pages[std::to_string(page->id())] = {{"frames_dropped", page->dropped_frames()}};
  return pages;
}

void Hub::remove(PageSession* page) {
  pages_.erase(page);
  stats_.pages = pages_.size();
}

void Hub::forward(const std::shared_ptr<PageSession>& page, v1::Request request) {
  const std::uint64_t id = next_id_++;
  pending_[id] = {page, request.id(), now()};
  request.set_id(id);
  link_->send(request.SerializeAsString());
  ++stats_.requests_forwarded;
}

void Hub::on_reply(const std::string& bytes) {
  v1::Reply reply;
  if (!reply.ParseFromString(bytes)) return;  // not from a phasecast server: nobody to tell
  const auto it = pending_.find(reply.id());
  if (it == pending_.end()) return;  // timed out already, or its page left
  const auto [page, page_id, sent_at] = it->second;
  pending_.erase(it);
  if (const auto p = page.lock()) p->reply_from_server(std::move(reply), page_id);
}

void Hub::on_frame(std::uint32_t instance, const std::string& bytes) {
  PageOutbox::Bytes event;  // built once, shared by every page that follows the instance
  for (const auto& [raw, page] : pages_) {
    if (!page->follows(instance)) continue;
    if (!event) event = std::make_shared<const std::string>(frame_event(bytes));
    page->send_frame(event);
  }
}

void Hub::expire_requests() {
  const double t = now();
  for (auto it = pending_.begin(); it != pending_.end();) {
    if (t - it->second.sent_at < options_.request_timeout_s) {
      ++it;
      continue;
    }
    if (const auto p = it->second.page.lock()) {
      v1::Reply reply;
      reply.set_id(it->second.page_id);
      reply.set_error(fmt::format("the server at {} did not answer within {:g} s", options_.server,
                                  options_.request_timeout_s));
      p->reply_from_server(std::move(reply), it->second.page_id);
    }
    ++stats_.requests_timed_out;
    it = pending_.erase(it);
  }
}

void Hub::schedule_expiry() {
  expiry_.expires_after(std::chrono::milliseconds(250));
  expiry_.async_wait([this](beast::error_code ec) {
    if (ec) return;
    expire_requests();
    schedule_expiry();
  });
}

std::string stats_json(const GatewayStats& s, nlohmann::json pages) {
  return nlohmann::json{{"open_pages", std::move(pages)},
                        {"pages", s.pages},
                        {"pages_total", s.pages_total},
                        {"pages_refused", s.pages_refused},
                        {"frames_forwarded", s.frames_forwarded},
                        {"frames_dropped", s.frames_dropped},
                        {"requests_forwarded", s.requests_forwarded},
                        {"requests_refused", s.requests_refused},
                        {"requests_timed_out", s.requests_timed_out},
                        {"bad_messages", s.bad_messages},
                        {"oversized_messages", s.oversized_messages},
                        {"bytes_sent", s.bytes_sent},
                        {"bytes_received", s.bytes_received}}
      .dump();
}

// One HTTP connection: GET of the page's files and /stats, or the upgrade of
// /ws into a PageSession.
class HttpSession : public std::enable_shared_from_this<HttpSession> {
 public:
  HttpSession(tcp::socket socket, Hub& hub, ConnectionSlot slot)
      : slot_(std::move(slot)), stream_(std::move(socket)), hub_(hub) {}

  void read() {
    parser_.emplace();
    parser_->body_limit(8 * 1024);  // pages only GET; nothing large comes in
    stream_.expires_after(std::chrono::seconds(30));
    http::async_read(stream_, buffer_, *parser_,
                     [self = shared_from_this()](beast::error_code ec, std::size_t) {
                       if (ec) return;  // closed, timed out or not HTTP: nothing to answer
                       self->on_request(self->parser_->release());
                     });
  }

 private:
  void on_request(http::request<http::string_body> req) {
    if (websocket::is_upgrade(req)) return upgrade(std::move(req));
    if (req.method() != http::verb::get && req.method() != http::verb::head) {
      return respond(text(req, http::status::method_not_allowed, "only GET and HEAD are served\n"));
    }
    if (req.target() == "/stats")
      return respond(
          text(req, http::status::ok, stats_json(hub_.stats(), hub_.page_stats()), "application/json"));
    serve_file(req);
  }

  void upgrade(http::request<http::string_body> req) {
    if (req.target() != "/ws") return respond(text(req, http::status::not_found, "WebSocket is at /ws\n"));
    const auto origin = req[http::field::origin];
    const auto host = req[http::field::host];
    if (!origin_allowed({origin.data(), origin.size()}, {host.data(), host.size()},
                        hub_.options().allow_origins)) {
      ++hub_.stats().pages_refused;
      return respond(text(req, http::status::forbidden,
                          fmt::format("pages from {} may not connect here (--allow-origin)\n",
                                      std::string_view(origin.data(), origin.size()))));
    }
    if (!hub_.admit()) {
      ++hub_.stats().pages_refused;
      return respond(
          text(req, http::status::service_unavailable,
               fmt::format("too many pages (at most {}, --max-pages)\n", hub_.options().max_pages)));
    }
    stream_.expires_never();                           // the WebSocket keeps its own timeouts
    stream_.socket().set_option(tcp::no_delay(true));  // frames are small: no Nagle delay
    // A small kernel send buffer keeps a slow page's backlog in the outbox,
    // where old frames are dropped, instead of megabytes of stale frames in
    // the kernel (Linux grows it up to tcp_wmem's maximum otherwise).
    beast::error_code ec;
    stream_.socket().set_option(
        asio::socket_base::send_buffer_size(static_cast<int>(hub_.options().page_send_buffer)), ec);
    hub_.opening_handshake();
    std::make_shared<PageSession>(stream_.release_socket(), hub_, std::move(*slot_))->accept(std::move(req));
    slot_.reset();
  }

  void serve_file(const http::request<http::string_body>& req) {
    const auto path =
        resolve_static(hub_.options().web_root, std::string_view(req.target().data(), req.target().size()));
    if (!path) return respond(text(req, http::status::bad_request, "this path is not served\n"));
    http::file_body::value_type file;
    beast::error_code ec;
    std::error_code regular_ec;
    if (std::filesystem::is_regular_file(*path, regular_ec))
      file.open(path->c_str(), beast::file_mode::scan, ec);
    if (!file.is_open()) {
      const bool no_page = !std::filesystem::exists(hub_.options().web_root / "index.html");
      return respond(text(req, http::status::not_found,
                          no_page ? fmt::format("the page is not built in {} (build the project with npm "
                                                "available, or pass --web-root)\n",
                                                hub_.options().web_root.string())
                                  : std::string("not found\n")));
    }
    const auto size = file.size();
    const auto headers = [&](auto& res) {
      res.set(http::field::server, kServerName);
      res.set(http::field::content_type, content_type(*path));
      res.set(http::field::cache_control, "no-cache");
      res.content_length(size);
      res.keep_alive(req.keep_alive());
    };
    if (req.method() == http::verb::head) {  // the headers of a GET, no body
      http::response<http::empty_body> res{http::status::ok, req.version()};
      headers(res);
      return respond(std::move(res));
    }
    http::response<http::file_body> res{std::piecewise_construct, std::make_tuple(std::move(file)),
                                        std::make_tuple(http::status::ok, req.version())};
    headers(res);
    respond(std::move(res));
  }

  static http::response<http::string_body> text(const http::request<http::string_body>& req,
                                                http::status status, std::string body,
                                                const char* type = "text/plain; charset=utf-8") {
    http::response<http::string_body> res{status, req.version()};
    res.set(http::field::server, kServerName);
    res.set(http::field::content_type, type);
    res.set(http::field::cache_control, "no-cache");
    res.keep_alive(req.keep_alive());
    if (req.method() != http::verb::head) res.body() = std::move(body);
    res.prepare_payload();
    return res;
  }

  template <class Body>
  void respond(http::response<Body>&& res) {
    auto shared = std::make_shared<http::response<Body>>(std::move(res));
    http::async_write(stream_, *shared,
                      [self = shared_from_this(), shared](beast::error_code ec, std::size_t) {
                        if (ec) return;
                        if (shared->need_eof()) {
                          self->stream_.socket().shutdown(tcp::socket::shutdown_send, ec);
                          return;
                        }
                        self->read();
                      });
  }

  std::optional<ConnectionSlot> slot_;  // moves to the page on upgrade
  beast::tcp_stream stream_;
  Hub& hub_;
  beast::flat_buffer buffer_;
  std::optional<http::request_parser<http::string_body>> parser_;
};

}  // namespace

struct Gateway::Impl {
  asio::io_context loop{1};
  tcp::acceptor acceptor{loop};
  asio::signal_set signals{loop, SIGINT, SIGTERM};
  asio::steady_timer backoff{loop};
  std::unique_ptr<Hub> hub;  // destroyed before the loop (its link thread posts into it)

  void accept() {
    acceptor.async_accept([this](beast::error_code ec, tcp::socket socket) {
      if (!acceptor.is_open()) return;
      if (ec) {  // e.g. out of file descriptors: try again shortly, do not spin
        backoff.expires_after(std::chrono::milliseconds(100));
        backoff.async_wait([this](beast::error_code e) {
          if (!e) accept();
        });
        return;
      }
      if (auto slot = hub->take_connection()) {
        std::make_shared<HttpSession>(std::move(socket), *hub, std::move(*slot))->read();
      }  // else: over the bound, the socket closes here
      accept();
    });
  }
};

namespace {

std::string pub_endpoint_of(const GatewayOptions& o) {
  const auto timeout = std::chrono::milliseconds(static_cast<long>(o.connect_timeout_s * 1000));
  client::CommandClient command(o.server, timeout, 1, o.curve);
  const auto scenes = command.list_scenes();
  return client::resolve_pub_endpoint(scenes.pub_endpoint(), o.server);
}

}  // namespace

Gateway::Gateway(GatewayOptions options) : impl_(std::make_unique<Impl>()) {
  const auto endpoint = parse_listen(options.listen);
  const auto pub = pub_endpoint_of(options);
  impl_->hub = std::make_unique<Hub>(impl_->loop, options, pub);
  auto& a = impl_->acceptor;
  a.open(endpoint.protocol());
  a.set_option(asio::socket_base::reuse_address(true));
  beast::error_code ec;
  a.bind(endpoint, ec);
  if (ec)
    throw std::runtime_error(fmt::format("--listen {}: cannot bind ({})", options.listen, ec.message()));
  a.listen(asio::socket_base::max_listen_connections);
}

Gateway::~Gateway() {
  impl_->hub.reset();
}

std::string Gateway::url() const {
  const auto e = impl_->acceptor.local_endpoint();
  return fmt::format("http://{}:{}/", e.address().to_string(), e.port());
}

void Gateway::run() {
  impl_->signals.async_wait([this](beast::error_code ec, int) {
    if (!ec) stop();
  });
  impl_->accept();
  impl_->loop.run();
}

void Gateway::stop() {
  asio::post(impl_->loop, [impl = impl_.get()] {
    beast::error_code ec;
    impl->acceptor.close(ec);
    impl->loop.stop();
  });
}

GatewayStats Gateway::stats() const {
  return impl_->hub->stats();
}

}  // namespace phasecast::gateway
