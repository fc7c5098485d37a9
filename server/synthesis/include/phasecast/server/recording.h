#pragma once
// Recording while serving, and checking a recording by replaying it. The
// format itself (magic, framing, reader, RecordingError) is
// phasecast/core/recording.h; this is what writes it as the stream goes.
// The tick only serializes into memory: a writer thread owns the file,
// writes what each tick queued and fsyncs at least once per second and at
// close, so a slow disk never delays a tick.

#include "phasecast/core/recording.h"
#include "phasecast/proto/phasecast.pb.h"
#include "phasecast/server/synthesis_engine.h"

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <thread>
#include <vector>

namespace phasecast::server {

// The service and the recorder name these unqualified; they are core's.
using core::kRecordingFormatVersion;
using core::RecordingError;

class RecordingWriter {
 public:
  // Creates `path`, which must not exist (O_EXCL | O_NOFOLLOW: a recording
  // never replaces a file, nor follows a link), queues the magic and
  // `header`, and starts the writer thread. The recording ends with a reason
  // once it would pass `max_bytes`.
  RecordingWriter(std::filesystem::path path, const v1::RecordingHeader& header,
                  std::uint64_t max_bytes = kNoSizeCap);
  // Closes as close() does, but reports nothing; a failed writer is left to
  // wind down on its own thread, so this never waits for the disk then.
  ~RecordingWriter();
  RecordingWriter(const RecordingWriter&) = delete;
  RecordingWriter& operator=(const RecordingWriter&) = delete;

  // Serializes one entry into the tick's buffer.
  void append(const v1::RecordEntry& entry);
  // Queues what the tick buffered for the writer thread. Throws
  // RecordingError when the recording has ended: a write or fsync failed,
  // the queue passed `max_queued_bytes` (the disk fell behind), or the file
  // would pass its size cap. Everything queued before stays in the file.
  void end_tick();
  // Waits for the queue to be written, fsyncs and closes; later calls do
  // nothing. Throws RecordingError if any write failed.
  void close();

  const std::filesystem::path& path() const { return path_; }
  std::uint64_t frames_written() const { return frames_; }
  std::uint64_t bytes_queued() const { return bytes_; }  // the file's size once written

  static constexpr std::chrono::milliseconds sync_every{1000};
  static constexpr std::uint64_t kNoSizeCap = ~std::uint64_t{0};
  static constexpr std::size_t max_queued_bytes = 64u << 20;

 private:
  struct Shared;  // the queue, the file and the writer's verdict, shared with its thread

  std::filesystem::path path_;
  std::shared_ptr<Shared> shared_;
  std::thread writer_;
  std::string buffer_;
  std::uint64_t frames_ = 0;       // queued for the writer
  std::uint64_t tick_frames_ = 0;  // in buffer_
  std::uint64_t bytes_ = 0;
  std::uint64_t max_bytes_;
};

struct ReplayReport {
  std::uint64_t frames = 0;    // recorded frames reproduced
  std::uint64_t impulses = 0;  // recorded impulses re-applied
  std::size_t instances = 0;   // instances seen
};

// Re-runs the `created`, `impulse` and `destroyed` entries (those of
// core::read_recording_file, the header first) on `engine` (its scenes
// loaded, no instances) and checks that every recorded frame is
// reproduced bit for bit. Throws RecordingError at the first difference, for
// a scene whose package hash differs from the header's, or for entries out
// of order.
ReplayReport replay_check(SynthesisEngine& engine, const std::vector<v1::RecordEntry>& entries);

}  // namespace phasecast::server
