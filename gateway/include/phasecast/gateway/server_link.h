#pragma once
// The gateway's two connections to phasecast-server (docs/protocol.md): a
// DEALER on the command socket, over which every page's requests go (with the
// gateway's own request ids), and a SUB on the frame stream. ZeroMQ sockets
// belong to one thread; this one runs its own and hands what arrives to the
// callbacks on that thread (the gateway posts them into its event loop).

#include "phasecast/client/network.h"

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>

namespace phasecast::gateway {

struct ServerLinkOptions {
  std::string command_endpoint;  // tcp://host:port of the server's ROUTER
  std::string pub_endpoint;      // as resolved from SceneList.pub_endpoint
  client::CurveClientKeys curve;
  std::chrono::milliseconds connect_timeout{5000};  // for the command connection at start
};

class ServerLink {
 public:
  using OnReply = std::function<void(std::string reply_bytes)>;
  using OnFrame = std::function<void(std::uint32_t instance, std::string frame_bytes)>;

  // Throws std::runtime_error when the command connection is not up within
  // the options' connect_timeout.
  ServerLink(ServerLinkOptions options, OnReply on_reply, OnFrame on_frame);
  ~ServerLink();  // stops and joins the ZeroMQ thread
  ServerLink(const ServerLink&) = delete;
  ServerLink& operator=(const ServerLink&) = delete;

  // Queues a serialized Request for the server. Call from one thread only
  // (the gateway's event loop): the queue's sending end is that thread's.
  void send(std::string request_bytes);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace phasecast::gateway
