#pragma once
// The recording format (docs/protocol.md, "Recording"), the one definition
// that the server's recorder and replay check and the client's --replay share:
// "PHCREC1\n", then varint-length-delimited RecordEntry messages, the first
// one the header.
//
// Why in core: records are phasecast.v1 messages, so this module needs
// phasecast_proto. That library depends on protobuf alone, never on core,
// server or client, so phasecast_core links it without a cycle; a library of
// its own would only add a target that server and client both link anyway.

#include "phasecast/proto/phasecast.pb.h"

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

namespace phasecast::core {

inline constexpr char kRecordingMagic[] = "PHCREC1\n";  // no terminator on disk
inline constexpr std::size_t kRecordingMagicSize = sizeof(kRecordingMagic) - 1;
inline constexpr std::uint32_t kRecordingFormatVersion = 1;
// Far above any Frame (hundreds of bytes): a larger length means corruption.
inline constexpr std::uint32_t kMaxRecordBytes = 64u << 20;

// A file that cannot be written or read as a recording (and, in the server, a
// replay that differs); one line naming the file and what was expected.
class RecordingError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Appends one record to `out`: the varint length, then the serialized entry.
void append_record(const v1::RecordEntry& entry, std::string& out);

// The first bytes of every recording: the magic and the `header` record.
std::string recording_prologue(const v1::RecordingHeader& header);

struct Recording {
  std::vector<v1::RecordEntry> entries;  // in file order; the first is the header
  bool truncated = false;                // the last record was cut short (a crash) and dropped

  const v1::RecordingHeader& header() const { return entries.front().header(); }
};

// Every record of the recording at `path`. A truncated final record (a crash
// while writing) is dropped and flagged. Throws RecordingError for a file that
// cannot be read, a wrong magic, a record that is too long or does not parse,
// a first record that is not a header, or a format version other than
// kRecordingFormatVersion.
Recording read_recording_file(const std::filesystem::path& path);

}  // namespace phasecast::core
