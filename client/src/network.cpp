#include "phasecast/client/network.h"

#include "phasecast/core/basis.h"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <zmq.hpp>
#include <zmq_addon.hpp>

#include <algorithm>
#include <array>
#include <cstring>
#include <regex>
#include <type_traits>
#include <variant>

namespace phasecast::client {
namespace {

// One context for the process: sockets come and go on reconnects.
zmq::context_t& context() {
  static zmq::context_t ctx(1);
  return ctx;
}

// The sizes the part shapes of docs/protocol.md depend on, as the server lists them.
core::BasisSizes sizes_of(const v1::SceneInfo& s) {
  return {s.points(), s.triangles(), s.rank_u(), s.rank_a()};
}

// The table entry of a listed part, after checking its dtype, shape and size
// against what the table promises for a scene of this size.
const core::BasisPartSpec& checked_spec(const v1::BasisPartInfo& info, const v1::SceneInfo& scene) {
  const auto* spec = core::find_basis_part_spec(info.part());
  if (!spec) {
    throw NetworkError(fmt::format("scene '{}': basis part {} is unknown (expected MEAN_SHAPE..U_A)",
                                   scene.name(), static_cast<int>(info.part())));
  }
  const auto expected = spec->shape(sizes_of(scene));
  const std::vector<std::uint64_t> shape(info.shape().begin(), info.shape().end());
  if (info.dtype() != spec->dtype || shape != expected) {
    throw NetworkError(fmt::format("scene '{}': basis part {} is {} [{}] (expected {} [{}])", scene.name(),
                                   spec->name, info.dtype(), fmt::join(shape, ", "), spec->dtype,
                                   fmt::join(expected, ", ")));
  }
  std::uint64_t count = 1;
  for (auto n : shape) count *= n;
  if (info.total_bytes() != count * spec->element_bytes) {
    throw NetworkError(fmt::format("scene '{}': basis part {} has total_bytes {} (expected {} for its shape)",
                                   scene.name(), spec->name, info.total_bytes(),
                                   count * spec->element_bytes));
  }
  return *spec;
}

// A chunk must continue the part exactly where the bytes so far end, from the
// same package the scene was listed from.
void check_chunk(const v1::BasisChunk& chunk, const v1::SceneInfo& scene, const std::string& name,
                 std::uint64_t done, std::uint64_t total) {
  if (chunk.content_hash() != scene.content_hash()) {
    throw NetworkError(
        fmt::format("basis {} {}: content hash changed during the download ({:016x}, expected "
                    "{:016x}); the server reloaded the package, reconnect",
                    scene.name(), name, chunk.content_hash(), scene.content_hash()));
  }
  if (chunk.offset() != done || chunk.data().empty() || chunk.data().size() > total - done) {
    throw NetworkError(
        fmt::format("basis {} {}: chunk at offset {} with {} bytes (expected offset {} and 1..{} "
                    "bytes)",
                    scene.name(), name, chunk.offset(), chunk.data().size(), done, total - done));
  }
}

using Progress = std::function<void(const std::string&, std::uint64_t, std::uint64_t)>;

// The bytes of one part, requested in chunks of at most `chunk_bytes`.
std::string download_part(CommandClient& client, const v1::SceneInfo& scene, const v1::BasisPartInfo& info,
                          const std::string& name, std::uint32_t chunk_bytes, const Progress& progress) {
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
        client.call(r, fmt::format("basis {} {} at byte {}", scene.name(), name, bytes.size())).basis();
    check_chunk(chunk, scene, name, bytes.size(), info.total_bytes());
    bytes += chunk.data();
    if (progress) progress(name, bytes.size(), info.total_bytes());
  }
  return bytes;
}

template <class T>
std::vector<T> as_vector(const std::string& bytes) {
  std::vector<T> v(bytes.size() / sizeof(T));
  if (!v.empty()) std::memcpy(v.data(), bytes.data(), v.size() * sizeof(T));
  return v;
}

// The ClientBasis member each part fills: the client's own layout, the one
// fact about a part the core table cannot hold. checked_spec has matched the
// part's dtype, which is the member's element type.
template <class T>
using Field = std::vector<T> ClientBasis::*;
using PartField = std::variant<Field<float>, Field<std::uint32_t>, Field<std::uint8_t>>;

struct PartDestination {
  core::BasisPartId id;
  PartField field;
};

constexpr std::array<PartDestination, core::kBasisPartCount> kDestinations = {{
    {core::BasisPartId::mean_shape, &ClientBasis::mean_shape},
    {core::BasisPartId::triangles, &ClientBasis::triangles},
    {core::BasisPartId::normals, &ClientBasis::normals},
    {core::BasisPartId::deformable, &ClientBasis::deformable},
    {core::BasisPartId::attached, &ClientBasis::attached},
    {core::BasisPartId::U_u, &ClientBasis::U_u},
    {core::BasisPartId::mean_transfer, &ClientBasis::mean_transfer},
    {core::BasisPartId::U_a, &ClientBasis::U_a},
}};

void store(ClientBasis& b, core::BasisPartId id, const std::string& bytes) {
  const auto it = std::find_if(kDestinations.begin(), kDestinations.end(),
                               [&](const PartDestination& d) { return d.id == id; });
  if (it == kDestinations.end()) return;
  std::visit(
      [&](auto field) {
        auto& member = b.*field;
        member = as_vector<typename std::remove_reference_t<decltype(member)>::value_type>(bytes);
      },
      it->field);
}

// The sizes and camera of the scene; the parts are filled in as they arrive.
ClientBasis basis_header(const v1::SceneInfo& scene) {
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
  return b;
}

}  // namespace

std::string basis_part_name(v1::BasisPart part) {
  const auto* spec = core::find_basis_part_spec(part);
  return spec ? std::string(spec->name) : fmt::format("part {}", static_cast<int>(part));
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
  ClientBasis b = basis_header(scene);
  for (const auto& info : scene.parts()) {
    const auto& spec = checked_spec(info, scene);
    store(b, spec.id, download_part(*this, scene, info, std::string(spec.name), chunk_bytes, progress));
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
