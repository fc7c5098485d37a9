#pragma once
// Recording while serving, and checking a recording by replaying it. The
// format itself (magic, framing, reader, RecordingError) is
// phasecast/core/recording.h; this is what writes it as the stream goes,
// fsync'd at least once per second and at close.

#include "phasecast/core/recording.h"
#include "phasecast/proto/phasecast.pb.h"
#include "phasecast/server/synthesis_engine.h"

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace phasecast::server {

// The service and the recorder name these unqualified; they are core's.
using core::kRecordingFormatVersion;
using core::RecordingError;

class RecordingWriter {
 public:
  // Creates (truncates) `path` and writes the magic and `header`.
  RecordingWriter(std::filesystem::path path, const v1::RecordingHeader& header);
  ~RecordingWriter();
  RecordingWriter(const RecordingWriter&) = delete;
  RecordingWriter& operator=(const RecordingWriter&) = delete;

  // Buffers one entry; end_tick() hands the buffer to the OS.
  void append(const v1::RecordEntry& entry);
  // Writes what the tick buffered; fsyncs when the last sync is `sync_every` old.
  void end_tick(std::chrono::steady_clock::time_point now);
  // Writes, fsyncs and closes; later calls do nothing.
  void close();

  const std::filesystem::path& path() const { return path_; }
  std::uint64_t frames_written() const { return frames_; }

  static constexpr std::chrono::milliseconds sync_every{1000};

 private:
  void flush_buffer();

  std::filesystem::path path_;
  int fd_ = -1;
  std::string buffer_;
  std::uint64_t frames_ = 0;
  std::chrono::steady_clock::time_point last_sync_;
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
