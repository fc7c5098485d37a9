#pragma once
// Recordings (docs/protocol.md, "Recording"): "PHCREC1\n", then varint-length
// delimited RecordEntry messages, the first one the header. Written as the
// stream goes, fsync'd at least once per second and at close.

#include "phasecast/proto/phasecast.pb.h"
#include "phasecast/server/synthesis_engine.h"

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

namespace phasecast::server {

inline constexpr char kRecordingMagic[] = "PHCREC1\n";  // 8 bytes, no terminator on disk
inline constexpr std::uint32_t kRecordingFormatVersion = 1;

// Thrown for files that cannot be written or read as recordings, and by
// replay_check when the replay differs; one line naming the file or frame.
class RecordingError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

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

// Every entry of a recording, in order; a truncated final record (a crash
// while writing) ends the list cleanly. Throws RecordingError for a missing
// file, a wrong magic, a first entry that is not a header, or a corrupt record.
std::vector<v1::RecordEntry> read_recording(const std::filesystem::path& path);

struct ReplayReport {
  std::uint64_t frames = 0;    // recorded frames reproduced
  std::uint64_t impulses = 0;  // recorded impulses re-applied
  std::size_t instances = 0;   // instances seen
};

// Re-runs the `created`, `impulse` and `destroyed` entries on `engine` (its
// scenes loaded, no instances) and checks that every recorded frame is
// reproduced bit for bit. Throws RecordingError at the first difference, for
// a scene whose package hash differs from the header's, or for entries out
// of order.
ReplayReport replay_check(SynthesisEngine& engine, const std::vector<v1::RecordEntry>& entries);

}  // namespace phasecast::server
