#pragma once
// A small in-test peer for the client, speaking docs/protocol.md from a
// package held in memory: a ROUTER that answers list_scenes, list_instances,
// create_instance and basis requests, and a PUB that publishes one instance's
// frames (an IRF of the package's portrait, looped). It exists only so the
// client can be tested before the real server lands; it is not a server.
// Also: a writer for recordings (docs/protocol.md "Recording").

#include "phasecast/core/curve_keys.h"
#include "phasecast/core/package.h"
#include "phasecast/proto/phasecast.pb.h"

#include <atomic>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <set>
#include <string>
#include <thread>
#include <vector>

namespace phasecast::testing {

struct PeerOptions {
  std::uint64_t content_hash = 0x1234;
  std::uint32_t instance = 1;
  int irf = 0;                          // IRF published, looped
  int period_ms = 5;                    // between frames
  std::set<std::uint64_t> skip_seq;     // sequence numbers never published (gap tests)
  std::set<std::uint64_t> corrupt_seq;  // published with one q_u value too many
  std::string cmd_endpoint = "tcp://127.0.0.1:*";
  std::string pub_endpoint = "tcp://127.0.0.1:*";
  bool wildcard_pub_host = true;   // announce pub_endpoint as tcp://0.0.0.0:PORT
  std::uint32_t max_chunk = 4096;  // small chunks so downloads take several requests
  std::uint64_t max_frames = 0;    // stop publishing after this many (0: never)
  // Publish only after this many complete basis downloads were served, and
  // hold_extra_ms after the last (clients subscribe after their GL setup).
  int hold_until_downloads = 0;
  int hold_extra_ms = 600;
  // CURVE: with a secret key (Z85) both sockets are CURVE servers; with
  // allowed_clients as well, a ZAP handler admits only those public keys.
  std::string curve_secret;
  std::set<std::string> allowed_clients;
};

class TestPeer {
 public:
  TestPeer(const core::ScenePackage& package, PeerOptions options);
  ~TestPeer();
  TestPeer(const TestPeer&) = delete;
  TestPeer& operator=(const TestPeer&) = delete;

  const std::string& cmd_endpoint() const { return cmd_endpoint_; }
  const std::string& pub_endpoint() const { return pub_endpoint_; }
  std::uint64_t frames_published() const { return published_; }
  std::uint64_t basis_requests() const { return basis_requests_; }
  // ZAP requests refused (clients not on allowed_clients).
  std::uint64_t refused_clients() const { return refused_clients_; }
  // The Frame for state node t of the published IRF, as the peer sends it.
  v1::Frame frame_at(std::uint64_t seq) const;

 private:
  void serve();
  void answer_zap();
  v1::Reply answer(const v1::Request& request);

  const core::ScenePackage& package_;
  PeerOptions options_;
  std::string cmd_endpoint_, pub_endpoint_;
  std::atomic<bool> stop_{false};
  std::atomic<std::uint64_t> published_{0}, basis_requests_{0}, refused_clients_{0};
  int downloads_done_ = 0;  // serve() thread only
  std::chrono::steady_clock::time_point last_download_{};
  struct Sockets;
  std::unique_ptr<Sockets> sockets_;
  std::thread thread_;
};

// A fresh CURVE key pair (zmq_curve_keypair), Z85.
core::CurveKeyPair make_curve_key_pair();

// Writes "PHCREC1\n", a header naming `package_file` with `content_hash`,
// a `created` entry and then every frame, each varint-length-delimited.
void write_recording(const std::filesystem::path& path, const std::string& scene,
                     const std::string& package_file, std::uint64_t content_hash,
                     const std::vector<v1::Frame>& frames);

// Frames of instance 1 playing IRF `irf` of the package (frame = seq = t).
std::vector<v1::Frame> irf_stream(const core::ScenePackage& package, int irf, std::uint32_t instance = 1);

}  // namespace phasecast::testing
