#pragma once
// The client side of docs/protocol.md: a command connection (DEALER, with
// Lazy Pirate retries: a request that times out is retried on a fresh
// socket), the chunked basis download that makes the client thin (§5.3), a
// frame subscriber on the instance's topic and sequence-gap counting, with
// optional CURVE encryption and authentication of both connections.
// ZeroMQ stays private to the implementation.

#include "phasecast/client/client_basis.h"
#include "phasecast/proto/phasecast.pb.h"

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace phasecast::client {

// Transport failures (server not answering) and refused requests; one line.
class NetworkError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// No reply after every attempt: the server is down or cannot be reached (a
// refusal is a plain NetworkError).
class NoReplyError : public NetworkError {
 public:
  using NetworkError::NetworkError;
};

// CURVE keys of a client (CurveZMQ; the server's side is its
// --curve-secret-key and --allow-clients), as Z85 text. Without a server key
// the connections are plain.
struct CurveClientKeys {
  std::string server_public;  // the server's long-term public key (its NAME.pub)
  std::string client_public;  // this client's pair: from NAME.key, or ephemeral
  std::string client_secret;
  bool enabled() const { return !server_public.empty(); }
};

// The keys of --server-key FILE (the server's NAME.pub) and --client-key FILE
// (this client's NAME.key); an empty path is an option not given. Neither:
// no CURVE. --server-key alone: a fresh ephemeral pair, which only a server
// without an allow-list accepts. Throws std::invalid_argument, one line
// naming the option and the file.
CurveClientKeys load_curve_client_keys(const std::filesystem::path& server_key,
                                       const std::filesystem::path& client_key);

class CommandClient {
 public:
  CommandClient(std::string endpoint, std::chrono::milliseconds timeout, int attempts,
                CurveClientKeys curve = {});
  ~CommandClient();
  CommandClient(const CommandClient&) = delete;
  CommandClient& operator=(const CommandClient&) = delete;

  const std::string& endpoint() const { return endpoint_; }
  // Tries per request from now on (at least 1).
  void set_attempts(int attempts);

  // Sends `request` (its id is set here) and returns the reply's result.
  // Throws NoReplyError when no reply comes after every attempt (naming what
  // the connection saw, e.g. a refused CURVE key), and NetworkError when the
  // server answers ok = false ("<what>: server refused: <error>").
  v1::Reply call(v1::Request request, const std::string& what);

  // Connections to the server completed so far (handshakes, over every
  // socket a retry opened). It grows when the server restarted, which no
  // reply says: a client that caches what the server told it re-checks then.
  std::uint64_t connections();

  v1::SceneList list_scenes();
  v1::InstanceList list_instances();
  v1::InstanceInfo create_instance(const std::string& scene);

  // Downloads every basis part the scene lists, in chunks of at most
  // `chunk_bytes`, and checks each chunk's content hash against the scene's.
  // `progress(part_name, done_bytes, total_bytes)` is called per chunk.
  ClientBasis download_basis(
      const v1::SceneInfo& scene, std::uint32_t chunk_bytes,
      const std::function<void(const std::string&, std::uint64_t, std::uint64_t)>& progress);

 private:
  struct Impl;
  std::string endpoint_;
  std::unique_ptr<Impl> impl_;
  std::uint64_t next_id_ = 1;
};

// Instances per FrameBatch: ids [1024 b, 1024 (b + 1)) share block b
// (docs/protocol.md, "Frames").
inline constexpr std::uint32_t kFrameBatchBlock = 1024;

class FrameSubscriber {
 public:
  // Connects a SUB socket to `endpoint` and subscribes to "inst/<instance>/".
  FrameSubscriber(const std::string& endpoint, std::uint32_t instance, const CurveClientKeys& curve = {});
  // Several instances of `scene`: one subscription per block of ids they
  // fall in ("scene/<scene>/<block>/", one FrameBatch per block and tick);
  // one instance: its own Frames.
  FrameSubscriber(const std::string& endpoint, const std::string& scene, std::vector<std::uint32_t> instances,
                  const CurveClientKeys& curve = {});
  ~FrameSubscriber();
  FrameSubscriber(const FrameSubscriber&) = delete;
  FrameSubscriber& operator=(const FrameSubscriber&) = delete;

  // The next frame, or nullopt after `timeout` without one. Returns nullopt
  // early, once, when the connection to the publisher came back after it was
  // lost (take_reconnected() then says so), so that the caller can re-check
  // the server before it takes frames from a restarted one. Messages that do
  // not parse or belong to another instance are counted and skipped.
  std::optional<v1::Frame> receive(std::chrono::milliseconds timeout);
  // The frames of the followed instances in the next message (a Frame, or
  // those a FrameBatch holds, in id order), as receive() does; empty when it
  // would return nullopt.
  std::vector<v1::Frame> receive_all(std::chrono::milliseconds timeout);
  std::uint64_t malformed() const { return malformed_; }

  // True once for each time the connection to the publisher was lost and
  // made again (ZeroMQ reconnects by itself; a restarted server shows here).
  bool take_reconnected();
  // Why frames may not be coming, from the connection's events: "" when it
  // is up or nothing is known, else e.g. "the server refused this client's
  // CURVE key (...)".
  std::string connection_problem();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::vector<std::uint32_t> instances_;  // sorted
  std::uint64_t malformed_ = 0;
};

// The frames of `instances` (sorted) that a FrameBatch holds, as the Frames
// the server would publish for them; throws std::invalid_argument when the
// batch's fields do not add up.
std::vector<v1::Frame> frames_of_batch(const v1::FrameBatch& batch,
                                       const std::vector<std::uint32_t>& instances);

// Per-instance sequence numbers (Frame.seq): counts the frames missed in gaps
// and the restarts of the stream (seq going back: a restarted server).
struct SequenceTracker {
  std::optional<std::uint64_t> last;
  std::uint64_t missed = 0;
  std::uint64_t gaps = 0;
  std::uint64_t restarts = 0;
  // True when `seq` restarted the stream.
  bool observe(std::uint64_t seq);
};

// SceneList.pub_endpoint with a wildcard host ("*", "0.0.0.0") replaced by
// the host of the command endpoint. Throws NetworkError for an empty or
// malformed endpoint.
std::string resolve_pub_endpoint(const std::string& pub_endpoint, const std::string& command_endpoint);

// Basis part name as in docs/protocol.md ("U_u", "MEAN_SHAPE" -> "mean_shape").
std::string basis_part_name(v1::BasisPart part);

}  // namespace phasecast::client
