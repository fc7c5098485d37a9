#include "phasecast/client/network.h"

#include "phasecast/core/basis.h"
#include "phasecast/core/curve_keys.h"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <zmq.hpp>
#include <zmq_addon.hpp>

#include <algorithm>
#include <array>
#include <atomic>
#include <cerrno>
#include <cstring>
#include <regex>
#include <set>
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
  if (scene.has_view()) {
    const auto& v = scene.view();
    b.floor = !v.no_floor();
    if (v.has_floor_height()) b.floor_height = v.floor_height();
    b.light = v.light();
    if (v.has_exposure()) b.exposure = v.exposure();
  }
  return b;
}

// zmq::poll, where a signal (Ctrl-C, SIGTERM) counts as "nothing yet": the
// caller's loop then sees the interrupt flag and ends cleanly.
int poll_items(zmq::pollitem_t* items, std::size_t count, std::chrono::milliseconds timeout) {
  try {
    return zmq::poll(items, count, timeout);
  } catch (const zmq::error_t& e) {
    if (e.num() == EINTR) return 0;
    throw;
  }
}

// ---- connection events --------------------------------------------------------

// What the connections of one client socket went through. ZeroMQ connects and
// reconnects by itself and tells only its socket monitor: this is how a client
// learns that its server went away and came back, and why a handshake failed.
struct ConnectionEvents {
  std::uint64_t connects = 0;     // TCP connections made
  std::uint64_t handshakes = 0;   // of those, ZMTP (and CURVE) handshakes completed
  std::string failure;            // the last failed handshake, in words; "" after a good one
  bool failure_detailed = false;  // the server said why (ZAP status, mechanism): kept over "closed"
};

// A failed handshake in words, naming the option that fixes it.
std::string handshake_failure(std::uint16_t event, std::uint32_t value, bool curve) {
  if (event == ZMQ_EVENT_HANDSHAKE_FAILED_AUTH) {
    return fmt::format(
        "the server refused this client's CURVE key (ZAP status {}; is its public key in the server's "
        "--allow-clients file?)",
        value);
  }
  if (event == ZMQ_EVENT_HANDSHAKE_FAILED_PROTOCOL && value == ZMQ_PROTOCOL_ERROR_ZMTP_MECHANISM_MISMATCH) {
    return curve ? "the server does not use CURVE (it was started without --curve-secret-key; drop "
                   "--server-key)"
                 : "the server requires CURVE (give --server-key with the server's public key file)";
  }
  if (event == ZMQ_EVENT_HANDSHAKE_FAILED_PROTOCOL) {
    return fmt::format("the {}handshake failed (ZMTP protocol error 0x{:x}{})", curve ? "CURVE " : "", value,
                       curve ? "; is --server-key this server's public key?" : "");
  }
  // No detail: the server closed the connection in the middle, which is what
  // a CURVE server does with a hello it cannot decrypt or a plain greeting.
  const std::string why = value ? fmt::format(" ({})", zmq_strerror(static_cast<int>(value))) : "";
  return curve ? fmt::format(
                     "the server closed the connection during the CURVE handshake{} (is --server-key "
                     "this server's public key, and does the server use CURVE?)",
                     why)
               : fmt::format(
                     "the server closed the connection during the handshake{} (is this its command "
                     "endpoint, --cmd, not its --pub port? A server that requires CURVE does that too: give "
                     "--server-key)",
                     why);
}

constexpr int kMonitoredEvents = ZMQ_EVENT_CONNECTED | ZMQ_EVENT_HANDSHAKE_SUCCEEDED |
                                 ZMQ_EVENT_HANDSHAKE_FAILED_NO_DETAIL | ZMQ_EVENT_HANDSHAKE_FAILED_PROTOCOL |
                                 ZMQ_EVENT_HANDSHAKE_FAILED_AUTH;

// The monitor of one socket (zmq_socket_monitor) and the PAIR its events
// arrive on. Set up before the socket connects, so no event is missed.
class SocketMonitor {
 public:
  SocketMonitor(zmq::socket_t& socket, bool curve) : socket_(socket), curve_(curve) {
    static std::atomic<unsigned> counter{0};
    const std::string endpoint = fmt::format("inproc://phasecast-monitor-{}", counter++);
    if (zmq_socket_monitor(socket_.handle(), endpoint.c_str(), kMonitoredEvents) != 0) {
      throw NetworkError(fmt::format("cannot monitor a ZeroMQ socket: {}", zmq_strerror(zmq_errno())));
    }
    // The monitor sends from ZeroMQ's I/O thread and would wait there when
    // this side fell behind: no receive limit, and events are read often.
    pair_.set(zmq::sockopt::rcvhwm, 0);
    pair_.set(zmq::sockopt::linger, 0);
    pair_.connect(endpoint);
  }
  // Stops the monitor before its PAIR goes, so no event is sent to nobody.
  ~SocketMonitor() { zmq_socket_monitor(socket_.handle(), nullptr, 0); }
  SocketMonitor(const SocketMonitor&) = delete;
  SocketMonitor& operator=(const SocketMonitor&) = delete;

  zmq::socket_t& events_socket() { return pair_; }

  // Reads the pending events into `events` without waiting.
  void drain(ConnectionEvents& events) {
    for (;;) {
      std::vector<zmq::message_t> parts;
      if (!zmq::recv_multipart(pair_, std::back_inserter(parts), zmq::recv_flags::dontwait)) return;
      if (parts.size() != 2 || parts[0].size() != 6) continue;
      std::uint16_t event = 0;
      std::uint32_t value = 0;
      std::memcpy(&event, parts[0].data(), sizeof event);
      std::memcpy(&value, static_cast<const char*>(parts[0].data()) + sizeof event, sizeof value);
      if (event == ZMQ_EVENT_CONNECTED) {
        ++events.connects;
      } else if (event == ZMQ_EVENT_HANDSHAKE_SUCCEEDED) {
        ++events.handshakes;
        events.failure.clear();
        events.failure_detailed = false;
      } else if (event & kMonitoredEvents) {
        // Which side notices first is a race; the reason the server gave wins.
        const bool detailed = event != ZMQ_EVENT_HANDSHAKE_FAILED_NO_DETAIL;
        if (detailed || !events.failure_detailed) events.failure = handshake_failure(event, value, curve_);
        events.failure_detailed = events.failure_detailed || detailed;
      }
    }
  }

 private:
  zmq::socket_t& socket_;
  zmq::socket_t pair_{context(), zmq::socket_type::pair};
  bool curve_;
};

// Why a connection that should carry messages does not, as far as its events
// tell; "" when they tell nothing.
std::string connection_problem(const ConnectionEvents& e, bool curve) {
  if (!e.failure.empty()) return e.failure;
  if (e.connects > e.handshakes && e.handshakes == 0) {
    return curve
               ? "the server closes every connection during the CURVE handshake (is --server-key this "
                 "server's public key, and does the server use CURVE?)"
               : "the server closes every connection during the handshake (is this its command endpoint, "
                 "--cmd, not its --pub port? A server that requires CURVE does that too: give --server-key)";
  }
  return {};
}

void apply_curve(zmq::socket_t& socket, const CurveClientKeys& keys) {
  if (!keys.enabled()) return;
  socket.set(zmq::sockopt::curve_serverkey, keys.server_public);
  socket.set(zmq::sockopt::curve_publickey, keys.client_public);
  socket.set(zmq::sockopt::curve_secretkey, keys.client_secret);
}

// `read()` of a key file, its error naming the option too.
template <class Read>
auto read_key_file(const char* option, Read&& read) {
  try {
    return read();
  } catch (const core::KeyFileError& e) {
    throw std::invalid_argument(fmt::format("{}: {}", option, e.what()));
  }
}

}  // namespace

CurveClientKeys load_curve_client_keys(const std::filesystem::path& server_key,
                                       const std::filesystem::path& client_key) {
  CurveClientKeys keys;
  if (server_key.empty()) {
    if (!client_key.empty()) {
      throw std::invalid_argument(fmt::format(
          "--client-key {} needs --server-key FILE (the server's public key; CURVE authenticates both sides)",
          client_key.string()));
    }
    return keys;
  }
  if (!zmq_has("curve")) {
    throw std::invalid_argument(
        fmt::format("--server-key {}: this build's libzmq has no CURVE support", server_key.string()));
  }
  keys.server_public = read_key_file("--server-key", [&] { return core::read_public_key_file(server_key); });
  if (!client_key.empty()) {
    const auto pair = read_key_file("--client-key", [&] { return core::read_secret_key_file(client_key); });
    keys.client_public = pair.public_z85;
    keys.client_secret = pair.secret_z85;
    return keys;
  }
  // No identity of our own: a key pair for this process only, which a server
  // with an allow-list refuses.
  std::array<char, 41> pub{}, sec{};
  if (zmq_curve_keypair(pub.data(), sec.data()) != 0) {
    throw std::invalid_argument(fmt::format("--server-key {}: cannot make an ephemeral CURVE key pair: {}",
                                            server_key.string(), zmq_strerror(zmq_errno())));
  }
  keys.client_public = pub.data();
  keys.client_secret = sec.data();
  return keys;
}

namespace {}  // namespace

std::string basis_part_name(v1::BasisPart part) {
  const auto* spec = core::find_basis_part_spec(part);
  return spec ? std::string(spec->name) : fmt::format("part {}", static_cast<int>(part));
}

// ---- command connection ---------------------------------------------------------

struct CommandClient::Impl {
  std::string endpoint;
  std::chrono::milliseconds timeout;
  int attempts;
  CurveClientKeys curve;
  std::unique_ptr<zmq::socket_t> socket;
  std::unique_ptr<SocketMonitor> monitor;  // of `socket`, which must outlive it
  ConnectionEvents events;                 // summed over every socket so far

  void reconnect() {
    if (monitor) monitor->drain(events);
    monitor.reset();
    socket = std::make_unique<zmq::socket_t>(context(), zmq::socket_type::dealer);
    socket->set(zmq::sockopt::linger, 0);
    // A send may wait at most one attempt's timeout. A DEALER whose only
    // connection the server refused before the first request (a CURVE key
    // not on its allow-list) has no pipe to queue on and never gets one
    // (libzmq does not reconnect after a refused handshake): a blocking send
    // would wait forever, and --timeout would never be reached.
    socket->set(zmq::sockopt::sndtimeo, static_cast<int>(timeout.count()));
    apply_curve(*socket, curve);
    monitor = std::make_unique<SocketMonitor>(*socket, curve.enabled());
    socket->connect(endpoint);
  }

  // Queues `payload` as one request; false when it could not be sent within
  // the timeout, which counts as an attempt without a reply.
  bool send_request(const std::string& payload) {
    if (!socket->send(zmq::message_t(), zmq::send_flags::sndmore)) return false;
    return socket->send(zmq::buffer(payload), zmq::send_flags::none).has_value();
  }

  // The reply to `request` within one attempt's timeout, or nullopt.
  std::optional<v1::Reply> await_reply(const v1::Request& request, const std::string& what) {
    auto& s = *socket;
    zmq::pollitem_t item{static_cast<void*>(s), 0, ZMQ_POLLIN, 0};
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < deadline) {
      const auto left =
          std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
      if (poll_items(&item, 1, std::max(left, std::chrono::milliseconds(1))) <= 0) continue;
      std::vector<zmq::message_t> parts;
      (void)zmq::recv_multipart(s, std::back_inserter(parts));
      v1::Reply reply;
      if (parts.empty() ||
          !reply.ParseFromArray(parts.back().data(), static_cast<int>(parts.back().size()))) {
        throw NetworkError(fmt::format("{}: the reply from {} does not parse as a Reply", what, endpoint));
      }
      if (reply.id() != request.id() && reply.id() != 0) continue;  // a late answer to an abandoned attempt
      return reply;
    }
    return std::nullopt;
  }

  // "(is phasecast-server running?)", or what the connection saw instead.
  std::string no_reply_hint() {
    monitor->drain(events);
    const std::string problem = connection_problem(events, curve.enabled());
    return problem.empty() ? "is phasecast-server running?" : problem;
  }
};

CommandClient::CommandClient(std::string endpoint, std::chrono::milliseconds timeout, int attempts,
                             CurveClientKeys curve)
    : endpoint_(std::move(endpoint)), impl_(std::make_unique<Impl>()) {
  impl_->endpoint = endpoint_;
  impl_->timeout = timeout;
  impl_->attempts = std::max(1, attempts);
  impl_->curve = std::move(curve);
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
    if (impl_->send_request(payload)) {
      if (auto reply = impl_->await_reply(request, what)) {
        if (!reply->ok()) throw NetworkError(fmt::format("{}: server refused: {}", what, reply->error()));
        return *reply;
      }
    }
    if (attempt + 1 < impl_->attempts)
      impl_->reconnect();  // Lazy Pirate: a fresh socket drops the lost request
  }
  const std::string hint = impl_->no_reply_hint();
  impl_->reconnect();  // the next call starts on a fresh socket too
  throw NoReplyError(fmt::format("{}: no reply from {} after {} attempts of {} ms ({})", what, endpoint_,
                                 impl_->attempts, impl_->timeout.count(), hint));
}

void CommandClient::set_attempts(int attempts) {
  impl_->attempts = std::max(1, attempts);
}

std::uint64_t CommandClient::connections() {
  impl_->monitor->drain(impl_->events);
  return impl_->events.handshakes;
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
  std::unique_ptr<SocketMonitor> monitor;  // of `socket`, which must outlive it
  ConnectionEvents events;
  bool curve = false;
  std::uint64_t acknowledged = 0;  // handshakes take_reconnected() has answered for
  std::uint64_t returned_at = 0;   // handshakes receive() last returned early for

  // A connection was lost and made again and nobody has been told yet.
  bool reconnect_pending() const { return events.handshakes > 1 && events.handshakes != acknowledged; }
};

FrameSubscriber::FrameSubscriber(const std::string& endpoint, std::uint32_t instance,
                                 const CurveClientKeys& curve)
    : FrameSubscriber(endpoint, std::string(), {instance}, curve) {}

FrameSubscriber::FrameSubscriber(const std::string& endpoint, const std::string& scene,
                                 std::vector<std::uint32_t> instances, const CurveClientKeys& curve)
    : impl_(std::make_unique<Impl>()), instances_(std::move(instances)) {
  if (instances_.empty()) throw NetworkError("no instance to follow (expected at least one)");
  std::sort(instances_.begin(), instances_.end());
  impl_->socket.set(zmq::sockopt::linger, 0);
  if (instances_.size() == 1) {
    impl_->socket.set(zmq::sockopt::subscribe, fmt::format("inst/{}/", instances_[0]));
  } else {
    std::set<std::uint32_t> blocks;
    for (const auto id : instances_) blocks.insert(id / kFrameBatchBlock);
    for (const auto b : blocks)
      impl_->socket.set(zmq::sockopt::subscribe, fmt::format("scene/{}/{}/", scene, b));
  }
  apply_curve(impl_->socket, curve);
  impl_->curve = curve.enabled();
  impl_->monitor = std::make_unique<SocketMonitor>(impl_->socket, impl_->curve);
  try {
    impl_->socket.connect(endpoint);
  } catch (const zmq::error_t& e) {
    throw NetworkError(fmt::format("frame endpoint '{}' cannot be connected ({})", endpoint, e.what()));
  }
}

FrameSubscriber::~FrameSubscriber() = default;

std::optional<v1::Frame> FrameSubscriber::receive(std::chrono::milliseconds timeout) {
  auto frames = receive_all(timeout);
  if (frames.empty()) return std::nullopt;
  return std::move(frames.front());
}

std::vector<v1::Frame> frames_of_batch(const v1::FrameBatch& b, const std::vector<std::uint32_t>& instances) {
  const auto n = static_cast<std::size_t>(b.instance_size());
  const std::size_t ru = b.rank_u(), ra = b.rank_a();
  const auto sized = [n](int size, std::size_t per) { return static_cast<std::size_t>(size) == n * per; };
  if (!sized(b.frame_size(), 1) || !sized(b.q_u_size(), ru) || !sized(b.q_a_size(), ra) ||
      !sized(b.support_size(), 12) || !sized(b.palette_index_size(), 1) || !sized(b.irf_size(), 1) ||
      !sized(b.irf_t_size(), 1)) {
    throw std::invalid_argument(fmt::format("frame batch of '{}' block {}: fields do not hold {} instances",
                                            b.scene(), b.block(), n));
  }
  std::vector<v1::Frame> out;
  for (std::size_t i = 0; i < n; ++i) {
    if (!std::binary_search(instances.begin(), instances.end(), b.instance(static_cast<int>(i)))) continue;
    const int k = static_cast<int>(i);
    v1::Frame& f = out.emplace_back();
    f.set_instance(b.instance(k));
    f.set_seq(b.frame(k));
    f.set_frame(b.frame(k));
    f.set_sim_time(static_cast<double>(b.frame(k)) * b.dt());
    f.mutable_q_u()->Add(b.q_u().begin() + static_cast<int>(i * ru),
                         b.q_u().begin() + static_cast<int>((i + 1) * ru));
    f.mutable_q_a()->Add(b.q_a().begin() + static_cast<int>(i * ra),
                         b.q_a().begin() + static_cast<int>((i + 1) * ra));
    f.mutable_support()->Add(b.support().begin() + 12 * k, b.support().begin() + 12 * (k + 1));
    f.set_palette_index(b.palette_index(k));
    f.set_irf(b.irf(k));
    f.set_irf_t(b.irf_t(k));
    f.set_scene(b.scene());
  }
  return out;
}

namespace {

// The followed instances' frames in one [topic][payload] message; empty when
// it holds none of them or does not parse.
std::vector<v1::Frame> followed_frames(const std::vector<zmq::message_t>& parts,
                                       const std::vector<std::uint32_t>& instances) {
  if (parts.size() != 2) return {};
  const auto size = static_cast<int>(parts[1].size());
  if (parts[0].to_string_view().starts_with("scene/")) {
    v1::FrameBatch batch;
    if (!batch.ParseFromArray(parts[1].data(), size)) return {};
    try {
      return frames_of_batch(batch, instances);
    } catch (const std::invalid_argument&) {
      return {};
    }
  }
  v1::Frame frame;
  if (!frame.ParseFromArray(parts[1].data(), size) ||
      !std::binary_search(instances.begin(), instances.end(), frame.instance())) {
    return {};
  }
  return {frame};
}

}  // namespace

std::vector<v1::Frame> FrameSubscriber::receive_all(std::chrono::milliseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  std::array<zmq::pollitem_t, 2> items{
      {{static_cast<void*>(impl_->socket), 0, ZMQ_POLLIN, 0},
       {static_cast<void*>(impl_->monitor->events_socket()), 0, ZMQ_POLLIN, 0}}};
  for (;;) {
    impl_->monitor->drain(impl_->events);
    // Frames of a restarted server wait until the caller has looked at it.
    if (impl_->reconnect_pending() && impl_->returned_at != impl_->events.handshakes) {
      impl_->returned_at = impl_->events.handshakes;
      return {};
    }
    const auto left =
        std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    // Past the deadline one last look without waiting (timeout 0: a non-blocking read).
    if (poll_items(items.data(), items.size(), std::max(left, std::chrono::milliseconds(0))) <= 0) return {};
    if (items[0].revents & ZMQ_POLLIN) {
      std::vector<zmq::message_t> parts;
      (void)zmq::recv_multipart(impl_->socket, std::back_inserter(parts));
      auto frames = followed_frames(parts, instances_);
      if (!frames.empty()) return frames;
      ++malformed_;
    }
    if (left.count() <= 0) return {};
  }
}

bool FrameSubscriber::take_reconnected() {
  impl_->monitor->drain(impl_->events);
  const bool again = impl_->reconnect_pending();
  impl_->acknowledged = impl_->events.handshakes;
  return again;
}

std::string FrameSubscriber::connection_problem() {
  impl_->monitor->drain(impl_->events);
  return client::connection_problem(impl_->events, impl_->curve);
}

// ---- helpers --------------------------------------------------------------------

bool SequenceTracker::observe(std::uint64_t seq) {
  const bool restarted = last && seq <= *last;
  if (last && seq > *last + 1) {
    missed += seq - *last - 1;
    ++gaps;
  } else if (restarted) {
    ++restarts;
  }
  last = seq;
  return restarted;
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
