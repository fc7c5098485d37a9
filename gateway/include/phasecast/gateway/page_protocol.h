#pragma once
// What crosses the gateway's WebSocket (docs/gateway.md): a page sends
// PageMessage and receives PageEvent (proto/phasecast.proto, "Browser
// pages"). Pure functions and the per-page send queue, no sockets, so the
// policy is tested without a network.

#include "phasecast/proto/phasecast.pb.h"

#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

namespace phasecast::gateway {

// Why a page may not send `request` through the gateway; "" when it may.
// Pages list, download bases, read stats and send impulses; creating or
// destroying instances and recording stay with trusted clients (the console).
std::string refusal(const v1::Request& request);

// Name of the request's body ("impulse", "basis", ...), for messages.
std::string request_kind(const v1::Request& request);

// PageEvent{frame} around a Frame exactly as the server published it: the
// field's key and length are prepended, the frame is not decoded again.
std::string frame_event(std::string_view frame_bytes);
std::string reply_event(const v1::Reply& reply);
std::string error_event(const std::string& message);
std::string hello_event(const v1::GatewayHello& hello);

// The instance of a PUB topic "inst/<id>/"; nullopt for any other topic.
std::optional<std::uint32_t> topic_instance(std::string_view topic);

// A page's queue of events waiting for its WebSocket. Frames are bounded: a
// page that reads slower than the server publishes loses its oldest queued
// frames (it sees the gap in Frame.seq), so neither the gateway's memory nor
// the other pages wait for it. Replies and notices are never dropped; the
// gateway bounds them by the requests it lets a page have in flight.
class PageOutbox {
 public:
  enum class Kind { frame, reply, notice };
  using Bytes = std::shared_ptr<const std::string>;

  explicit PageOutbox(std::size_t frame_queue) : frame_queue_(frame_queue) {}

  void push(Kind kind, Bytes bytes);
  // The event to write next (it stays queued until written), or nullptr.
  Bytes start_write();
  // The event start_write() gave has been written: removes it, returns its kind.
  Kind finish_write();

  bool writing() const { return writing_; }
  std::size_t queued() const { return events_.size(); }
  std::uint64_t dropped_frames() const { return dropped_frames_; }

 private:
  struct Event {
    Kind kind;
    Bytes bytes;
  };
  void drop_oldest_waiting_frame();

  std::size_t frame_queue_;
  std::deque<Event> events_;
  std::size_t frames_waiting_ = 0;  // frames queued and not being written
  bool writing_ = false;
  std::uint64_t dropped_frames_ = 0;
};

// Requests per second a page may send, with bursts of `burst` (a token
// bucket). Time is passed in, so tests need no clock.
class RequestRate {
 public:
  RequestRate(double per_second, double burst) : rate_(per_second), burst_(burst), tokens_(burst) {}
  bool take(double now_seconds);

 private:
  double rate_, burst_, tokens_;
  double last_ = -1;
};

}  // namespace phasecast::gateway
