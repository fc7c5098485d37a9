#include "phasecast/client/network.h"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <zmq.hpp>
#include <zmq_addon.hpp>

#include <cstring>
#include <regex>

namespace phasecast::client {
namespace {

// One context for the process: sockets come and go on reconnects.
zmq::context_t& context() {
  static zmq::context_t ctx(1);
  return ctx;
}

std::size_t dtype_size(const std::string& dtype) {
  if (dtype == "float32" || dtype == "uint32") return 4;
  if (dtype == "uint8") return 1;
  return 0;
}

struct ExpectedPart {
  const char* dtype;
  std::vector<std::uint64_t> shape;
};

// What docs/protocol.md promises for each part of a scene of this size.
ExpectedPart expected_part(v1::BasisPart part, const v1::SceneInfo& s) {
  const std::uint64_t S = s.points(), F = s.triangles();
  switch (part) {
    case v1::MEAN_SHAPE:
    case v1::NORMALS:
      return {"float32", {S, 3}};
    case v1::TRIANGLES:
      return {"uint32", {F, 3}};
    case v1::DEFORMABLE:
    case v1::ATTACHED:
      return {"uint8", {S}};
    case v1::U_U:
      return {"float32", {3 * S, s.rank_u()}};
    case v1::MEAN_TRANSFER:
      return {"float32", {48 * S}};
    case v1::U_A:
      return {"float32", {48 * S, s.rank_a()}};
    default:
      throw NetworkError(fmt::format("scene '{}': basis part {} is unknown (expected MEAN_SHAPE..U_A)",
                                     s.name(), static_cast<int>(part)));
  }
}

template <class T>
std::vector<T> as_vector(const std::string& bytes) {
  std::vector<T> v(bytes.size() / sizeof(T));
  if (!v.empty()) std::memcpy(v.data(), bytes.data(), v.size() * sizeof(T));
  return v;
}

}  // namespace

std::string basis_part_name(v1::BasisPart part) {
  switch (part) {
    case v1::MEAN_SHAPE:
      return "mean_shape";
    case v1::TRIANGLES:
      return "triangles";
    case v1::NORMALS:
      return "normals";
    case v1::DEFORMABLE:
      return "deformable";
    case v1::ATTACHED:
      return "attached";
    case v1::U_U:
      return "U_u";
    case v1::MEAN_TRANSFER:
      return "mean_transfer";
    case v1::U_A:
      return "U_a";
    default:
      return fmt::format("part {}", static_cast<int>(part));
  }
}

// ---- command connection ---------------------------------------------------------

struct CommandClient::Impl {
  std::string endpoint;
  std::chrono::milliseconds timeout;
  int attempts;
  std::unique_ptr<zmq::socket_t> socket;

  void reconnect() {
    socket = std::make_unique<zmq::socket_t>(context(), zmq::socket_type::dealer);
    socket->set(zmq::sockopt::linger, 0);
    socket->connect(endpoint);
  }
};

CommandClient::CommandClient(std::string endpoint, std::chrono::milliseconds timeout, int attempts)
    : endpoint_(std::move(endpoint)), impl_(std::make_unique<Impl>()) {
  impl_->endpoint = endpoint_;
  impl_->timeout = timeout;
  impl_->attempts = std::max(1, attempts);
  try {
    impl_->reconnect();
  } catch (const zmq::error_t& e) {
    throw NetworkError(
        fmt::format("--connect '{}' is not a usable ZeroMQ endpoint ({}); expected e.g. "
                    "tcp://host:5555",
                    endpoint_, e.what()));
  }
}

CommandClient::~CommandClient() = default;

v1::Reply CommandClient::call(v1::Request request, const std::string& what) {
  request.set_id(next_id_++);
  const std::string payload = request.SerializeAsString();
  for (int attempt = 0; attempt < impl_->attempts; ++attempt) {
    auto& s = *impl_->socket;
    s.send(zmq::message_t(), zmq::send_flags::sndmore);
    s.send(zmq::buffer(payload), zmq::send_flags::none);
    zmq::pollitem_t item{static_cast<void*>(s), 0, ZMQ_POLLIN, 0};
    const auto deadline = std::chrono::steady_clock::now() + impl_->timeout;
    while (std::chrono::steady_clock::now() < deadline) {
      const auto left =
          std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
      if (zmq::poll(&item, 1, std::max(left, std::chrono::milliseconds(1))) <= 0) continue;
      std::vector<zmq::message_t> parts;
      (void)zmq::recv_multipart(s, std::back_inserter(parts));
      v1::Reply reply;
      if (parts.empty() ||
          !reply.ParseFromArray(parts.back().data(), static_cast<int>(parts.back().size()))) {
        throw NetworkError(fmt::format("{}: the reply from {} does not parse as a Reply", what, endpoint_));
      }
      if (reply.id() != request.id() && reply.id() != 0) continue;  // a late answer to an abandoned attempt
      if (!reply.ok()) throw NetworkError(fmt::format("{}: server refused: {}", what, reply.error()));
      return reply;
    }
    impl_->reconnect();  // Lazy Pirate: a fresh socket drops the lost request
  }
  throw NetworkError(
      fmt::format("{}: no reply from {} after {} attempts of {} ms (is phasecast-server running?)", what,
                  endpoint_, impl_->attempts, impl_->timeout.count()));
}

v1::SceneList CommandClient::list_scenes() {
  v1::Request r;
  r.mutable_list_scenes();
  return call(r, "list_scenes").scenes();
}

v1::InstanceList CommandClient::list_instances() {
  v1::Request r;
  r.mutable_list_instances();
  return call(r, "list_instances").instances();
}

v1::InstanceInfo CommandClient::create_instance(const std::string& scene) {
  v1::Request r;
  r.mutable_create_instance()->set_scene(scene);
  return call(r, fmt::format("create_instance {}", scene)).created();
}

ClientBasis CommandClient::download_basis(
    const v1::SceneInfo& scene, std::uint32_t chunk_bytes,
    const std::function<void(const std::string&, std::uint64_t, std::uint64_t)>& progress) {
  ClientBasis b;
  b.scene = scene.name();
  b.content_hash = scene.content_hash();
  b.points = static_cast<int>(scene.points());
  b.rank_u = static_cast<int>(scene.rank_u());
  b.rank_a = static_cast<int>(scene.rank_a());
  if (scene.camera_size() == 10) {
    std::array<float, 10> camera{};
    std::copy(scene.camera().begin(), scene.camera().end(), camera.begin());
    b.camera = camera;
  }
  for (const auto& info : scene.parts()) {
    const std::string name = basis_part_name(info.part());
    const auto expected = expected_part(info.part(), scene);
    const std::vector<std::uint64_t> shape(info.shape().begin(), info.shape().end());
    if (info.dtype() != expected.dtype || shape != expected.shape) {
      throw NetworkError(fmt::format("scene '{}': basis part {} is {} [{}] (expected {} [{}])", scene.name(),
                                     name, info.dtype(), fmt::join(shape, ", "), expected.dtype,
                                     fmt::join(expected.shape, ", ")));
    }
    std::uint64_t count = 1;
    for (auto n : shape) count *= n;
    if (info.total_bytes() != count * dtype_size(info.dtype())) {
      throw NetworkError(
          fmt::format("scene '{}': basis part {} has total_bytes {} (expected {} for its shape)",
                      scene.name(), name, info.total_bytes(), count * dtype_size(info.dtype())));
    }
    std::string bytes;
    bytes.reserve(info.total_bytes());
    while (bytes.size() < info.total_bytes()) {
      v1::Request r;
      auto* q = r.mutable_basis();
      q->set_scene(scene.name());
      q->set_part(info.part());
      q->set_offset(bytes.size());
      q->set_max_bytes(chunk_bytes);
      const auto chunk =
          call(r, fmt::format("basis {} {} at byte {}", scene.name(), name, bytes.size())).basis();
      if (chunk.content_hash() != scene.content_hash()) {
        throw NetworkError(
            fmt::format("basis {} {}: content hash changed during the download ({:016x}, expected "
                        "{:016x}); the server reloaded the package, reconnect",
                        scene.name(), name, chunk.content_hash(), scene.content_hash()));
      }
      if (chunk.offset() != bytes.size() || chunk.data().empty() ||
          chunk.data().size() > info.total_bytes() - bytes.size()) {
        throw NetworkError(
            fmt::format("basis {} {}: chunk at offset {} with {} bytes (expected offset {} and 1..{} "
                        "bytes)",
                        scene.name(), name, chunk.offset(), chunk.data().size(), bytes.size(),
                        info.total_bytes() - bytes.size()));
      }
      bytes += chunk.data();
      if (progress) progress(name, bytes.size(), info.total_bytes());
    }
    switch (info.part()) {
      case v1::MEAN_SHAPE:
        b.mean_shape = as_vector<float>(bytes);
        break;
      case v1::TRIANGLES:
        b.triangles = as_vector<std::uint32_t>(bytes);
        break;
      case v1::NORMALS:
        b.normals = as_vector<float>(bytes);
        break;
      case v1::DEFORMABLE:
        b.deformable = as_vector<std::uint8_t>(bytes);
        break;
      case v1::ATTACHED:
        b.attached = as_vector<std::uint8_t>(bytes);
        break;
      case v1::U_U:
        b.U_u = as_vector<float>(bytes);
        break;
      case v1::MEAN_TRANSFER:
        b.mean_transfer = as_vector<float>(bytes);
        break;
      case v1::U_A:
        b.U_a = as_vector<float>(bytes);
        break;
      default:
        break;
    }
  }
  b.validate(fmt::format("bases of scene '{}' from {}", scene.name(), endpoint_));
  return b;
}

// ---- frames ---------------------------------------------------------------------

struct FrameSubscriber::Impl {
  zmq::socket_t socket{context(), zmq::socket_type::sub};
};

FrameSubscriber::FrameSubscriber(const std::string& endpoint, std::uint32_t instance)
    : impl_(std::make_unique<Impl>()), instance_(instance) {
  impl_->socket.set(zmq::sockopt::linger, 0);
  impl_->socket.set(zmq::sockopt::subscribe, fmt::format("inst/{}/", instance));
  try {
    impl_->socket.connect(endpoint);
  } catch (const zmq::error_t& e) {
    throw NetworkError(fmt::format("frame endpoint '{}' cannot be connected ({})", endpoint, e.what()));
  }
}

FrameSubscriber::~FrameSubscriber() = default;

std::optional<v1::Frame> FrameSubscriber::receive(std::chrono::milliseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  zmq::pollitem_t item{static_cast<void*>(impl_->socket), 0, ZMQ_POLLIN, 0};
  for (;;) {
    const auto left =
        std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0 || zmq::poll(&item, 1, left) <= 0) return std::nullopt;
    std::vector<zmq::message_t> parts;
    (void)zmq::recv_multipart(impl_->socket, std::back_inserter(parts));
    v1::Frame frame;
    if (parts.size() != 2 || !frame.ParseFromArray(parts[1].data(), static_cast<int>(parts[1].size())) ||
        frame.instance() != instance_) {
      ++malformed_;
      continue;
    }
    return frame;
  }
}

// ---- helpers --------------------------------------------------------------------

void SequenceTracker::observe(std::uint64_t seq) {
  if (last && seq > *last + 1) {
    missed += seq - *last - 1;
    ++gaps;
  } else if (last && seq <= *last) {
    ++restarts;
  }
  last = seq;
}

std::string resolve_pub_endpoint(const std::string& pub, const std::string& command) {
  static const std::regex tcp(R"(^tcp://([^:/]+|\[[^\]]+\]):(\d+)$)");
  std::smatch p, c;
  if (pub.empty())
    throw NetworkError("list_scenes: the server sent no pub_endpoint (expected e.g. tcp://host:5556)");
  if (!std::regex_match(pub, p, tcp)) return pub;  // ipc:// and others are used as they are
  const std::string host = p[1];
  if (host != "*" && host != "0.0.0.0") return pub;
  if (!std::regex_match(command, c, tcp)) {
    throw NetworkError(fmt::format(
        "pub_endpoint '{}' has a wildcard host but the command endpoint '{}' names none", pub, command));
  }
  return fmt::format("tcp://{}:{}", c[1].str(), p[2].str());
}

}  // namespace phasecast::client
