#include "test_peer.h"

#include "phasecast/core/basis.h"

#include <fmt/format.h>
#include <zmq.hpp>
#include <zmq_addon.hpp>

#include <array>
#include <chrono>
#include <fstream>
#include <stdexcept>

namespace phasecast::testing {
namespace {

zmq::context_t& context() {
  static zmq::context_t ctx(1);
  return ctx;
}

std::string varint(std::uint64_t n) {
  std::string out;
  while (n >= 0x80) {
    out += static_cast<char>((n & 0x7f) | 0x80);
    n >>= 7;
  }
  out += static_cast<char>(n);
  return out;
}

}  // namespace

struct TestPeer::Sockets {
  zmq::socket_t zap{context(), zmq::socket_type::rep};  // bound only with an allow-list
  zmq::socket_t router{context(), zmq::socket_type::router};
  zmq::socket_t pub{context(), zmq::socket_type::pub};
};

core::CurveKeyPair make_curve_key_pair() {
  std::array<char, 41> pub{}, sec{};
  if (zmq_curve_keypair(pub.data(), sec.data()) != 0) throw std::runtime_error("zmq_curve_keypair failed");
  return {pub.data(), sec.data()};
}

std::vector<v1::Frame> irf_stream(const core::ScenePackage& p, int irf, std::uint32_t instance) {
  const auto& pp = p.portrait;
  std::vector<v1::Frame> frames;
  const auto i = static_cast<std::size_t>(irf);
  for (int t = 0; t < pp.irf_length[i]; ++t) {
    const int node = pp.irf_start[i] + t;
    v1::Frame f;
    f.set_instance(instance);
    f.set_seq(static_cast<std::uint64_t>(t));
    f.set_frame(static_cast<std::uint64_t>(t));
    f.set_sim_time(t * p.attributes.dt);
    for (Eigen::Index k = 0; k < pp.q_u.cols(); ++k) f.add_q_u(pp.q_u(node, k));
    for (Eigen::Index k = 0; k < pp.q_a.cols(); ++k) f.add_q_a(pp.q_a(node, k));
    for (Eigen::Index k = 0; k < pp.support.cols(); ++k) f.add_support(pp.support(node, k));
    f.set_palette_index(pp.irf_palette[i]);
    f.set_irf(irf);
    f.set_irf_t(static_cast<std::uint32_t>(t));
    f.set_scene(p.attributes.scene);
    frames.push_back(f);
  }
  return frames;
}

void write_recording(const std::filesystem::path& path, const std::string& scene,
                     const std::string& package_file, std::uint64_t content_hash,
                     const std::vector<v1::Frame>& frames) {
  std::ofstream out(path, std::ios::binary);
  out << "PHCREC1\n";
  auto put = [&](const v1::RecordEntry& e) {
    const std::string bytes = e.SerializeAsString();
    out << varint(bytes.size()) << bytes;
  };
  v1::RecordEntry header;
  header.mutable_header()->set_format_version(1);
  auto* s = header.mutable_header()->add_scenes();
  s->set_scene(scene);
  s->set_package(package_file);
  s->set_content_hash(content_hash);
  header.mutable_header()->set_rate_hz(60);
  put(header);
  v1::RecordEntry created;
  created.mutable_created()->set_instance(frames.empty() ? 1 : frames[0].instance());
  created.mutable_created()->set_scene(scene);
  put(created);
  for (const auto& f : frames) {
    v1::RecordEntry e;
    *e.mutable_frame() = f;
    put(e);
  }
}

TestPeer::TestPeer(const core::ScenePackage& package, PeerOptions options)
    : package_(package), options_(std::move(options)), sockets_(std::make_unique<Sockets>()) {
  sockets_->router.set(zmq::sockopt::linger, 0);
  sockets_->pub.set(zmq::sockopt::linger, 0);
  sockets_->zap.set(zmq::sockopt::linger, 0);
  if (!options_.allowed_clients.empty()) sockets_->zap.bind("inproc://zeromq.zap.01");  // ZAP's fixed address
  for (auto* socket : {&sockets_->router, &sockets_->pub}) {
    if (options_.curve_secret.empty()) continue;
    socket->set(zmq::sockopt::curve_server, true);
    socket->set(zmq::sockopt::curve_secretkey, options_.curve_secret);
  }
  sockets_->router.bind(options_.cmd_endpoint);
  sockets_->pub.bind(options_.pub_endpoint);
  cmd_endpoint_ = sockets_->router.get(zmq::sockopt::last_endpoint);
  pub_endpoint_ = sockets_->pub.get(zmq::sockopt::last_endpoint);
  thread_ = std::thread([this] { serve(); });
}

TestPeer::~TestPeer() {
  stop_ = true;
  thread_.join();
}

v1::Frame TestPeer::frame_at(std::uint64_t seq) const {
  const auto stream = irf_stream(package_, options_.irf, options_.instance);
  v1::Frame f = stream[seq % stream.size()];
  f.set_seq(seq);
  f.set_frame(seq);
  return f;
}

v1::Reply TestPeer::answer(const v1::Request& request) {
  v1::Reply reply;
  reply.set_id(request.id());
  reply.set_ok(true);
  const auto& p = package_;
  const std::string scene = p.attributes.scene;
  if (request.has_list_scenes()) {
    auto* list = reply.mutable_scenes();
    const auto port = pub_endpoint_.substr(pub_endpoint_.rfind(':') + 1);
    list->set_pub_endpoint(options_.wildcard_pub_host ? "tcp://0.0.0.0:" + port : pub_endpoint_);
    auto* s = list->add_scenes();
    s->set_name(scene);
    s->set_package("plate.h5");
    s->set_content_hash(options_.content_hash);
    s->set_points(static_cast<std::uint32_t>(p.mesh.points()));
    s->set_triangles(static_cast<std::uint32_t>(p.mesh.triangle_count()));
    s->set_rank_u(static_cast<std::uint32_t>(p.rank_u()));
    s->set_rank_a(static_cast<std::uint32_t>(p.rank_a()));
    s->set_state_nodes(static_cast<std::uint32_t>(p.portrait.nodes()));
    s->set_dt(p.attributes.dt);
    if (p.attributes.camera) {
      for (float c : *p.attributes.camera) s->add_camera(c);
    }
    for (const auto& part : core::basis_parts(p)) {
      auto* info = s->add_parts();
      info->set_part(static_cast<v1::BasisPart>(part.id));
      info->set_dtype(part.dtype);
      for (auto n : part.shape) info->add_shape(n);
      info->set_total_bytes(part.bytes.size());
    }
  } else if (request.has_list_instances()) {
    auto* i = reply.mutable_instances()->add_instances();
    i->set_instance(options_.instance);
    i->set_scene(scene);
    i->set_topic(fmt::format("inst/{}/", options_.instance));
  } else if (request.has_create_instance()) {
    if (request.create_instance().scene() != scene) {
      reply.set_ok(false);
      reply.set_error(fmt::format("create_instance: unknown scene '{}' (expected one of {})",
                                  request.create_instance().scene(), scene));
    } else {
      reply.mutable_created()->set_instance(options_.instance);
      reply.mutable_created()->set_scene(scene);
    }
  } else if (request.has_basis()) {
    ++basis_requests_;
    const auto& b = request.basis();
    for (const auto& part : core::basis_parts(p)) {
      if (static_cast<int>(part.id) != static_cast<int>(b.part())) continue;
      const std::uint32_t cap =
          b.max_bytes() == 0 ? options_.max_chunk : std::min(b.max_bytes(), options_.max_chunk);
      const auto offset = std::min<std::uint64_t>(b.offset(), part.bytes.size());
      const auto n = std::min<std::uint64_t>(cap, part.bytes.size() - offset);
      auto* chunk = reply.mutable_basis();
      chunk->set_scene(scene);
      chunk->set_part(b.part());
      chunk->set_offset(offset);
      chunk->set_total_bytes(part.bytes.size());
      chunk->set_data(reinterpret_cast<const char*>(part.bytes.data()) + offset, n);
      chunk->set_content_hash(options_.content_hash);
      if (b.part() == static_cast<v1::BasisPart>(core::basis_parts(p).back().id) &&
          offset + n == part.bytes.size()) {
        ++downloads_done_;  // the last part's last chunk: one client has all its bases
        last_download_ = std::chrono::steady_clock::now();
      }
    }
    if (!reply.has_basis()) {
      reply.set_ok(false);
      reply.set_error(fmt::format("basis: unknown part {}", static_cast<int>(b.part())));
    }
  } else {
    reply.set_ok(false);
    reply.set_error("test peer: request not supported");
  }
  return reply;
}

// ZAP (RFC 27): [version, request id, domain, address, identity, mechanism,
// client key] -> [version, request id, status, text, user id, metadata].
void TestPeer::answer_zap() {
  std::vector<zmq::message_t> parts;
  (void)zmq::recv_multipart(sockets_->zap, std::back_inserter(parts));
  if (parts.size() < 6) return;
  bool allowed = false;
  if (parts.size() == 7 && parts[6].size() == 32) {
    std::array<char, 41> z85{};
    zmq_z85_encode(z85.data(), static_cast<const std::uint8_t*>(parts[6].data()), 32);
    allowed = options_.allowed_clients.count(z85.data()) > 0;
  }
  if (!allowed) ++refused_clients_;
  const std::vector<std::string> reply{
      "1.0", parts[1].to_string(), allowed ? "200" : "400", allowed ? "OK" : "not on the allow-list", "", ""};
  std::vector<zmq::const_buffer> buffers;
  for (const auto& r : reply) buffers.push_back(zmq::buffer(r));
  zmq::send_multipart(sockets_->zap, buffers);
}

void TestPeer::serve() {
  using clock = std::chrono::steady_clock;
  auto next_frame = clock::now();
  std::uint64_t seq = 0;
  std::array<zmq::pollitem_t, 2> items{{{static_cast<void*>(sockets_->router), 0, ZMQ_POLLIN, 0},
                                        {static_cast<void*>(sockets_->zap), 0, ZMQ_POLLIN, 0}}};
  auto& item = items[0];
  while (!stop_) {
    zmq::poll(items.data(), items.size(), std::chrono::milliseconds(1));
    if (items[1].revents & ZMQ_POLLIN) answer_zap();
    if (item.revents & ZMQ_POLLIN) {
      std::vector<zmq::message_t> parts;
      (void)zmq::recv_multipart(sockets_->router, std::back_inserter(parts));
      if (parts.size() == 3) {
        v1::Request request;
        v1::Reply reply;
        if (request.ParseFromArray(parts[2].data(), static_cast<int>(parts[2].size()))) {
          reply = answer(request);
        } else {
          reply.set_ok(false);
          reply.set_error("request does not parse");
        }
        sockets_->router.send(parts[0], zmq::send_flags::sndmore);
        sockets_->router.send(zmq::message_t(), zmq::send_flags::sndmore);
        sockets_->router.send(zmq::buffer(reply.SerializeAsString()), zmq::send_flags::none);
      }
    }
    const bool held = downloads_done_ < options_.hold_until_downloads ||
                      (options_.hold_until_downloads > 0 &&
                       clock::now() < last_download_ + std::chrono::milliseconds(options_.hold_extra_ms));
    if (held) next_frame = clock::now();
    if (!held && clock::now() >= next_frame && (options_.max_frames == 0 || seq < options_.max_frames)) {
      next_frame += std::chrono::milliseconds(options_.period_ms);
      if (!options_.skip_seq.count(seq)) {
        const auto topic = fmt::format("inst/{}/", options_.instance);
        sockets_->pub.send(zmq::buffer(topic), zmq::send_flags::sndmore);
        v1::Frame frame = frame_at(seq);
        if (options_.corrupt_seq.count(seq)) frame.add_q_u(0.5f);
        sockets_->pub.send(zmq::buffer(frame.SerializeAsString()), zmq::send_flags::none);
        ++published_;
      }
      ++seq;
    }
  }
}

}  // namespace phasecast::testing
