#include "phasecast/gateway/page_protocol.h"

#include "phasecast/core/proto_oneof.h"

#include <fmt/format.h>

#include <algorithm>
#include <charconv>

namespace phasecast::gateway {
namespace {

// Protobuf key of a length-delimited field: (number << 3) | 2.
constexpr char kFrameKey = (v1::PageEvent::kFrameFieldNumber << 3) | 2;

void append_varint(std::string& out, std::uint64_t v) {
  while (v >= 0x80) {
    out.push_back(static_cast<char>((v & 0x7f) | 0x80));
    v >>= 7;
  }
  out.push_back(static_cast<char>(v));
}

std::string serialized(const v1::PageEvent& event) {
  std::string out;
  event.SerializeToString(&out);
  return out;
}

}  // namespace

std::string request_kind(const v1::Request& r) {
  const auto kind = core::oneof_case(r, "body");
  return kind.empty() ? "empty" : kind;
}

std::string refusal(const v1::Request& r) {
  switch (r.body_case()) {
    case v1::Request::kImpulse:
    case v1::Request::kListScenes:
    case v1::Request::kListInstances:
    case v1::Request::kBasis:
    case v1::Request::kStats:
      return {};
    case v1::Request::BODY_NOT_SET:
      return "request has no body (expected impulse, list_scenes, list_instances, basis or stats)";
    default:
      return fmt::format(
          "{} is not allowed through the gateway (pages may send impulse, list_scenes, list_instances, basis "
          "and stats; use phasecast-console to manage instances and recordings)",
          request_kind(r));
  }
}

std::string frame_event(std::string_view frame_bytes) {
  std::string out;
  out.reserve(frame_bytes.size() + 11);
  out.push_back(kFrameKey);
  append_varint(out, frame_bytes.size());
  out.append(frame_bytes);
  return out;
}

std::string reply_event(const v1::Reply& reply) {
  v1::PageEvent event;
  *event.mutable_reply() = reply;
  return serialized(event);
}

std::string error_event(const std::string& message) {
  v1::PageEvent event;
  event.mutable_error()->set_error(message);
  return serialized(event);
}

std::string hello_event(const v1::GatewayHello& hello) {
  v1::PageEvent event;
  *event.mutable_hello() = hello;
  return serialized(event);
}

std::optional<std::uint32_t> topic_instance(std::string_view topic) {
  constexpr std::string_view prefix = "inst/";
  if (!topic.starts_with(prefix) || !topic.ends_with('/') || topic.size() < prefix.size() + 2) return {};
  const auto digits = topic.substr(prefix.size(), topic.size() - prefix.size() - 1);
  std::uint32_t id = 0;
  const auto [end, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), id);
  if (ec != std::errc{} || end != digits.data() + digits.size()) return {};
  return id;
}

void PageOutbox::push(Kind kind, Bytes bytes) {
  if (kind == Kind::frame) {
    if (frames_waiting_ >= frame_queue_) drop_oldest_waiting_frame();
    ++frames_waiting_;
  }
  events_.push_back({kind, std::move(bytes)});
}

void PageOutbox::drop_oldest_waiting_frame() {
  // The front event may be on the wire already; it is not waiting.
  const auto first_waiting = events_.begin() + (writing_ ? 1 : 0);
  const auto it =
      std::find_if(first_waiting, events_.end(), [](const Event& e) { return e.kind == Kind::frame; });
  if (it == events_.end()) return;
  events_.erase(it);
  --frames_waiting_;
  ++dropped_frames_;
}

PageOutbox::Bytes PageOutbox::start_write() {
  if (writing_ || events_.empty()) return nullptr;
  writing_ = true;
  if (events_.front().kind == Kind::frame) --frames_waiting_;
  return events_.front().bytes;
}

PageOutbox::Kind PageOutbox::finish_write() {
  const Kind kind = events_.front().kind;
  events_.pop_front();
  writing_ = false;
  return kind;
}

bool RequestRate::take(double now) {
  if (last_ >= 0) tokens_ = std::min(burst_, tokens_ + (now - last_) * rate_);
  last_ = now;
  if (tokens_ < 1) return false;
  tokens_ -= 1;
  return true;
}

}  // namespace phasecast::gateway
