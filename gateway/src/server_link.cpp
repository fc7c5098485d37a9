#include "phasecast/gateway/server_link.h"

#include "phasecast/gateway/page_protocol.h"

#include <fmt/format.h>
#include <zmq.hpp>

#include <atomic>
#include <stdexcept>
#include <thread>
#include <vector>

namespace phasecast::gateway {
namespace {

constexpr const char* kQueueEndpoint = "inproc://phasecast-gateway-requests";

void apply_curve(zmq::socket_t& socket, const client::CurveClientKeys& keys) {
  if (!keys.enabled()) return;
  socket.set(zmq::sockopt::curve_serverkey, keys.server_public);
  socket.set(zmq::sockopt::curve_publickey, keys.client_public);
  socket.set(zmq::sockopt::curve_secretkey, keys.client_secret);
}

}  // namespace

struct ServerLink::Impl {
  zmq::context_t context{1};
  zmq::socket_t queue_in{context, zmq::socket_type::push};   // the event loop's end
  zmq::socket_t queue_out{context, zmq::socket_type::pull};  // the ZeroMQ thread's end
  zmq::socket_t command{context, zmq::socket_type::dealer};
  zmq::socket_t frames{context, zmq::socket_type::sub};
  std::atomic<bool> stop{false};
  std::string endpoint;
  OnReply on_reply;
  OnFrame on_frame;
  std::thread thread;

  void connect(const ServerLinkOptions& o) {
    for (auto* s : {&queue_in, &queue_out, &command, &frames}) s->set(zmq::sockopt::linger, 0);
    queue_out.bind(kQueueEndpoint);
    queue_in.connect(kQueueEndpoint);
    queue_in.set(zmq::sockopt::sndhwm, 0);  // pages are bounded by the gateway, not here
    // While the server is away nothing queues for it (a request then fails
    // by its timeout, and never reaches a restarted server late), and a full
    // queue never blocks this thread.
    command.set(zmq::sockopt::immediate, 1);
    command.set(zmq::sockopt::sndtimeo, 0);
    apply_curve(command, o.curve);
    apply_curve(frames, o.curve);
    command.connect(o.command_endpoint);
    endpoint = o.command_endpoint;
    // Under `immediate` the DEALER takes messages only once connected: wait
    // for that, so the first pages' requests are not refused.
    zmq::pollitem_t writable{command.handle(), 0, ZMQ_POLLOUT, 0};
    if (zmq::poll(&writable, 1, o.connect_timeout) == 0) {
      throw std::runtime_error(
          fmt::format("no connection to the server at {} within {} ms", endpoint, o.connect_timeout.count()));
    }
    // Every instance's frames: pages pick theirs in the gateway, so a new
    // subscription never waits for ZeroMQ's subscription round trip.
    frames.set(zmq::sockopt::subscribe, "inst/");
    frames.connect(o.pub_endpoint);
  }

  void run() {
    std::vector<zmq::pollitem_t> items = {{queue_out.handle(), 0, ZMQ_POLLIN, 0},
                                          {command.handle(), 0, ZMQ_POLLIN, 0},
                                          {frames.handle(), 0, ZMQ_POLLIN, 0}};
    while (!stop) {
      zmq::poll(items, std::chrono::milliseconds(100));
      if (items[0].revents & ZMQ_POLLIN) forward_requests();
      if (items[1].revents & ZMQ_POLLIN) take_replies();
      if (items[2].revents & ZMQ_POLLIN) take_frames();
    }
  }

  void forward_requests() {
    zmq::message_t m;
    while (queue_out.recv(m, zmq::recv_flags::dontwait)) {
      // A DEALER sends [empty delimiter][request], as the server's ROUTER expects
      // from REQ-style clients (docs/protocol.md).
      if (command.send(zmq::message_t(), zmq::send_flags::sndmore | zmq::send_flags::dontwait)) {
        (void)command.send(m, zmq::send_flags::dontwait);  // the rest of a message is always taken
      } else {
        refuse(m);
      }
    }
  }

  // The server is not connected (or its queue is full): the page hears so
  // now, and the request never reaches a server later.
  void refuse(const zmq::message_t& request_bytes) {
    v1::Request request;
    if (!request.ParseFromArray(request_bytes.data(), static_cast<int>(request_bytes.size()))) return;
    v1::Reply reply;
    reply.set_id(request.id());
    reply.set_error(fmt::format("the server at {} is not connected; the request was not sent", endpoint));
    on_reply(reply.SerializeAsString());
  }

  void take_replies() {
    zmq::message_t part;
    while (command.recv(part, zmq::recv_flags::dontwait)) {
      // Skip the empty delimiter; the last part is the reply.
      while (part.more() && command.recv(part, zmq::recv_flags::none)) {
      }
      on_reply(part.to_string());
    }
  }

  void take_frames() {
    zmq::message_t topic, frame;
    while (frames.recv(topic, zmq::recv_flags::dontwait)) {
      if (!topic.more() || !frames.recv(frame, zmq::recv_flags::none)) continue;
      while (frame.more()) (void)frames.recv(frame, zmq::recv_flags::none);  // not ours: drop extra parts
      if (const auto id = topic_instance(topic.to_string_view())) on_frame(*id, frame.to_string());
    }
  }
};

ServerLink::ServerLink(ServerLinkOptions options, OnReply on_reply, OnFrame on_frame)
    : impl_(std::make_unique<Impl>()) {
  impl_->on_reply = std::move(on_reply);
  impl_->on_frame = std::move(on_frame);
  impl_->connect(options);
  impl_->thread = std::thread([impl = impl_.get()] { impl->run(); });
}

ServerLink::~ServerLink() {
  impl_->stop = true;
  impl_->thread.join();
}

void ServerLink::send(std::string request_bytes) {
  impl_->queue_in.send(zmq::buffer(request_bytes), zmq::send_flags::none);
}

}  // namespace phasecast::gateway
