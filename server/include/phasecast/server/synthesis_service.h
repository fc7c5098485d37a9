#pragma once
// What phasecast-server does, minus the sockets and the clock: loads scene
// packages into a SynthesisEngine, answers every Request with one Reply,
// turns each tick into the published messages, and records the stream.
// The transport (server.h) moves these bytes; tests drive this directly too.

#include "phasecast/proto/phasecast.pb.h"
#include "phasecast/server/recording.h"
#include "phasecast/server/synthesis_engine.h"

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace phasecast::server {

inline constexpr std::uint32_t kDefaultChunkBytes = 1u << 20;  // basis chunk without max_bytes
inline constexpr std::uint32_t kMaxChunkBytes = 4u << 20;      // cap on max_bytes
inline constexpr std::size_t kDefaultMaxInstances = 100000;    // bounds what create_instance floods can cost

struct PublishedFrame {
  std::string topic;    // "inst/<id>/"
  std::string payload;  // serialized Frame
};

struct ServiceStats {
  std::uint64_t ticks = 0;
  std::uint64_t frames_published = 0;
  std::uint64_t late_ticks = 0;
  std::uint64_t requests = 0;
  std::uint64_t bad_requests = 0;
  std::uint64_t impulses_applied = 0;
  std::uint64_t impulses_refused = 0;
  double max_tick_seconds = 0;
};

class SynthesisService {
 public:
  explicit SynthesisService(double rate_hz);
  ~SynthesisService();

  // Reads and validates a package (core::PackageError on any problem) and
  // adds its scene; `blend_lambda` overrides the package's eq. 12 lambda.
  void load_package(const std::filesystem::path& package, std::optional<double> blend_lambda = std::nullopt);

  SynthesisEngine& engine() { return engine_; }
  const ServiceStats& stats() const { return stats_; }
  ServiceStats& stats() { return stats_; }
  void set_pub_endpoint(std::string endpoint) { pub_endpoint_ = std::move(endpoint); }
  // create_instance requests beyond this many instances are refused.
  void set_max_instances(std::size_t n) { max_instances_ = n; }
  // Where record_start requests (plain file names) write.
  void set_record_dir(std::filesystem::path dir) { record_dir_ = std::move(dir); }

  // One request payload in, one reply out; never throws. A payload that does
  // not parse gets Reply{id = 0, ok = false}.
  v1::Reply handle(std::string_view request_bytes);
  v1::Reply handle(const v1::Request& request);

  // Advances every instance one frame and returns their messages in id order;
  // the recording (if any) gets the applied impulses, then the frames.
  const std::vector<PublishedFrame>& tick(std::chrono::steady_clock::time_point now);

  // Starts writing the stream to `path` (RecordingError if already recording
  // or the file cannot be created); stop() closes it with an fsync.
  void start_recording(const std::filesystem::path& path);
  v1::RecordStatus stop_recording();
  bool recording() const { return recorder_ != nullptr; }
  // Why the last recording ended on its own (a write failed); empty if none did.
  const std::string& recording_error() const { return recording_error_; }

 private:
  // answer() fills the reply for the request's kind with one of the functions
  // after it; each throws (EngineError, RequestError, RecordingError) to refuse.
  void answer(const v1::Request& request, v1::Reply& reply);
  void impulse(const v1::Impulse& request, v1::ImpulseAccepted& out);
  void list_scenes(v1::SceneList& out) const;
  void list_instances(v1::Reply& reply) const;
  void create_instance(const v1::CreateInstance& request, v1::InstanceInfo& out);
  void destroy_instance(const v1::DestroyInstance& request, v1::InstanceInfo& out);
  void basis(const v1::BasisRequest& request, v1::BasisChunk& out) const;
  void record_start(const v1::RecordStart& request, v1::RecordStatus& out);
  void record_stop(v1::RecordStatus& out);
  void report_stats(v1::Stats& out) const;

  void instance_info(std::uint32_t id, v1::InstanceInfo& out) const;
  void record_created(std::uint32_t id);
  void record_destroyed(const v1::InstanceInfo& info);
  void record_impulses(const std::vector<AppliedImpulse>& applied);
  const std::vector<PublishedFrame>& tick_and_record(std::chrono::steady_clock::time_point now);

  double rate_hz_;
  SynthesisEngine engine_;
  ServiceStats stats_;
  std::string pub_endpoint_;
  std::filesystem::path record_dir_ = ".";
  std::unique_ptr<RecordingWriter> recorder_;
  std::string recording_error_;
  std::size_t max_instances_ = kDefaultMaxInstances;
  std::vector<PublishedFrame> published_;
  TickResult tick_result_;  // reused across ticks, like frame_, to keep its storage
  v1::Frame frame_;         // reused across ticks
};

}  // namespace phasecast::server
