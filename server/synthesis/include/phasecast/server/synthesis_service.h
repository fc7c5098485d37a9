#pragma once
// What phasecast-server does, minus the sockets and the clock: loads scene
// packages into a SynthesisEngine, answers every Request with one Reply,
// turns each tick into the published messages, and records the stream.
// The transport (server.h) moves these bytes; tests drive this directly too.
//
// Thread safety: once serving, the tick thread calls tick() while the command
// thread calls handle(); both take one mutex around the engine, the stats and
// the recorder. Basis requests read only the loaded packages, which never
// change after start, so they are answered (and their chunk copied) without
// it: a large download never holds up a tick.

#include "phasecast/proto/phasecast.pb.h"
#include "phasecast/server/recording.h"
#include "phasecast/server/synthesis_engine.h"
#include "phasecast/server/topic_interest.h"

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

namespace phasecast::server {

inline constexpr std::uint32_t kDefaultChunkBytes = 1u << 20;  // basis chunk without max_bytes
inline constexpr std::uint32_t kMaxChunkBytes = 1u << 20;      // cap on max_bytes (bounds queued reply bytes)
// Replies up to this size are sent whatever the pending-reply bounds say: an
// error reply always reaches its client, and small replies cost little.
inline constexpr std::uint64_t kRepliesAlwaysSent = 1024;

// What one client may cost the server; a request over a limit gets an error
// reply naming the limit and its option (docs/server.md, "Limits").
struct ServiceLimits {
  std::size_t max_instances = 1024;             // --max-instances: all clients together
  std::size_t max_instances_per_client = 64;    // --max-instances-per-client
  double impulse_horizon_s = 600;               // --impulse-horizon: how far ahead at_frame may lie
  double max_request_rate = 1000;               // --max-request-rate: requests/s per client (burst 1 s)
  std::uint64_t record_max_bytes = 4ull << 30;  // --record-max-bytes: one recording ends at this size
  // Reply bytes queued for clients and not yet written to their connections
  // (slow readers' basis chunks): a basis chunk that would pass either bound
  // is refused. The per-client one keeps a few stalled clients from using up
  // the global one, which would refuse every downloader.
  std::uint64_t max_pending_reply_bytes = 256ull << 20;            // --max-pending-reply-bytes: all clients
  std::uint64_t max_pending_reply_bytes_per_client = 16ull << 20;  // --max-pending-reply-bytes-per-client
};

// The transport's count of reply bytes handed to ZeroMQ and not yet written.
struct PendingReplyBytes {
  std::uint64_t all = 0;     // every client together
  std::uint64_t client = 0;  // the asking client
};

struct PublishedFrame {
  std::string topic;    // "inst/<id>/" or "scene/<scene>/<block>/"
  std::string payload;  // serialized Frame or FrameBatch
};

struct ServiceStats {
  std::uint64_t ticks = 0;
  std::uint64_t frames_published = 0;   // Frame messages
  std::uint64_t batches_published = 0;  // FrameBatch messages
  std::uint64_t late_ticks = 0;
  std::uint64_t requests = 0;
  std::uint64_t bad_requests = 0;
  std::uint64_t impulses_applied = 0;
  std::uint64_t impulses_refused = 0;
  double max_tick_seconds = 0;
  std::uint64_t limited_requests = 0;  // refused by a limit (also counted in bad_requests)
};

class SynthesisService {
 public:
  explicit SynthesisService(double rate_hz);
  ~SynthesisService();

  // Reads and validates a package (core::PackageError on any problem) and
  // adds its scene; `blend_lambda` overrides the package's eq. 12 lambda.
  void load_package(const std::filesystem::path& package, std::optional<double> blend_lambda = std::nullopt);

  // The engine, unlocked: for start-up, replay and tests, not while serving.
  SynthesisEngine& engine() { return engine_; }
  ServiceStats stats() const;
  void set_pub_endpoint(std::string endpoint) { pub_endpoint_ = std::move(endpoint); }
  void set_limits(const ServiceLimits& limits) { limits_ = limits; }
  const ServiceLimits& limits() const { return limits_; }
  // Where record_start requests (plain *.phcrec names) write; created on first use.
  void set_record_dir(std::filesystem::path dir) { record_dir_ = std::move(dir); }
  // The transport's count of queued reply bytes for a client (as named to
  // handle()); set before serving, called by basis requests and stats from
  // any thread.
  using PendingReplyCount = std::function<PendingReplyBytes(const std::string& client)>;
  void set_pending_reply_bytes(PendingReplyCount count) { pending_reply_bytes_ = std::move(count); }

  // One request payload in, one reply out; never throws. A payload that does
  // not parse gets Reply{id = 0, ok = false}. `client` names the sender (its
  // CURVE key or connection) for the per-client limits; empty: no such limits.
  v1::Reply handle(std::string_view request_bytes, const std::string& client = {});
  v1::Reply handle(const v1::Request& request, const std::string& client = {});

  // The transport's own counts: a message that is not a request envelope or
  // is over the size limit, and the timing of one tick as it measured it.
  void count_bad_message();
  void count_tick(double seconds, bool late);

  // Advances every instance one frame and returns the messages someone
  // subscribes to (set_subscriptions): each instance's Frame in id order and
  // each scene's FrameBatch per block of ids; the recording (if any) gets the
  // applied impulses, then every instance's Frame. The result is the
  // caller's until its next tick() call.
  const std::vector<PublishedFrame>& tick();
  // The topic prefixes subscribers hold (the transport's XPUB socket reports
  // them). Until set: "inst/", every instance's Frame and no batch.
  void set_subscriptions(std::set<std::string> prefixes);

  // Starts writing the stream to `path`, a new file (RecordingError if
  // already recording or the file exists or cannot be created); stop closes
  // it with an fsync, outside the lock so the tick does not wait for it.
  void start_recording(const std::filesystem::path& path);
  v1::RecordStatus stop_recording();
  bool recording() const;
  // Why the last recording ended on its own (write failed, the disk fell
  // behind, the size cap); empty if none did.
  std::string recording_error() const;

 private:
  // answer() fills the reply for the request's kind with one of the functions
  // after it; each throws (EngineError, RequestError, RecordingError) to refuse.
  // What an InstanceInfo says, taken under the lock; the messages of a
  // listing (stats, list_instances) are written after it is released.
  struct InstanceRow {
    std::uint32_t id = 0;
    const std::string* scene = nullptr;  // scenes never change once serving
    std::uint64_t frame = 0;
    std::int32_t palette_index = -1, irf = -1;
    std::uint32_t irf_t = 0;
    std::vector<int> allowed;
  };
  void answer(const v1::Request& request, const std::string& client, v1::Reply& reply,
              std::vector<InstanceRow>& rows);
  void check_rate(const std::string& client);
  void impulse(const v1::Impulse& request, v1::ImpulseAccepted& out);
  void list_scenes(v1::SceneList& out) const;
  void list_instances(std::vector<InstanceRow>& rows) const;
  void create_instance(const v1::CreateInstance& request, const std::string& client, v1::InstanceInfo& out);
  void destroy_instance(const v1::DestroyInstance& request, v1::InstanceInfo& out);
  void basis(const v1::BasisRequest& request, v1::BasisChunk& out) const;
  void check_pending_replies(const std::string& client, std::uint64_t reply_bytes) const;
  void record_start(const v1::RecordStart& request, v1::RecordStatus& out);
  void record_stop(v1::RecordStatus& out);
  void report_stats(v1::Stats& out, std::vector<InstanceRow>& rows) const;
  InstanceRow instance_row(std::uint32_t id) const;
  static void write_instance(const InstanceRow& row, v1::InstanceInfo& out);
  static void write_instances(const std::vector<InstanceRow>& rows,
                              google::protobuf::RepeatedPtrField<v1::InstanceInfo>* out);

  void instance_info(std::uint32_t id, v1::InstanceInfo& out) const;
  void record_created(std::uint32_t id);
  void record_destroyed(const v1::InstanceInfo& info);
  void record_impulses(const std::vector<AppliedImpulse>& applied);
  void tick_and_record();
  void publish(std::string topic, const google::protobuf::Message& message);
  void add_to_batch(const SynthesizedFrame& frame);
  void close_batch(std::size_t scene);
  void start_recording_locked(const std::filesystem::path& path);
  std::unique_ptr<RecordingWriter> take_recorder(v1::RecordStatus& status);

  // A client's token bucket for --max-request-rate.
  struct RateBucket {
    double tokens = 0;
    std::chrono::steady_clock::time_point last;
  };

  double rate_hz_;
  mutable std::mutex mutex_;  // engine instances, stats, recorder, client books
  SynthesisEngine engine_;
  ServiceStats stats_;
  std::string pub_endpoint_;
  std::filesystem::path record_dir_ = "recordings";
  PendingReplyCount pending_reply_bytes_ = [](const std::string&) { return PendingReplyBytes{}; };
  std::unique_ptr<RecordingWriter> recorder_;
  std::unique_ptr<RecordingWriter> closing_;  // stopped by a request, closed after the lock is released
  std::string recording_error_;
  ServiceLimits limits_;
  std::map<std::uint32_t, std::string> owner_;       // instance -> client that created it
  std::map<std::string, std::size_t> instances_of_;  // client -> instances it created
  std::map<std::string, RateBucket> buckets_;        // client -> request budget
  std::vector<PublishedFrame> published_;            // its first published_count_ are this tick's
  std::size_t published_count_ = 0;
  TopicInterest interest_;
  // Per scene: the block of ids whose batch is being filled, and whether anyone wants it.
  struct OpenBatch {
    std::optional<std::uint32_t> block;
    bool wanted = false;
  };
  std::vector<OpenBatch> open_batches_;
  std::vector<v1::FrameBatch> batches_;  // per scene, reused across ticks
  TickResult tick_result_;               // reused across ticks, like frame_, to keep its storage
  v1::Frame frame_;                      // reused across ticks
};

}  // namespace phasecast::server
