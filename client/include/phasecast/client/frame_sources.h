#pragma once
// Frames without a server (local mode): the package's own phase portrait
// (one IRF played node by node) or a recording of a published stream
// (docs/protocol.md "Recording").

#include "phasecast/client/frame_state.h"
#include "phasecast/core/package.h"
#include "phasecast/proto/phasecast.pb.h"

#include <filesystem>
#include <optional>
#include <stdexcept>
#include <vector>

namespace phasecast::client {

class RecordingError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// The state nodes of IRF `irf` as frames 0..length-1 (q_u, q_a and, when the
// package stores it, the simulated support transform). Throws
// std::invalid_argument when `irf` is out of range.
std::vector<FrameState> portrait_frames(const core::ScenePackage& package, int irf);

FrameState frame_state(const v1::Frame& frame);

struct Recording {
  v1::RecordingHeader header;
  std::vector<v1::RecordEntry> entries;  // everything after the header, in file order
  bool truncated = false;                // the last record was cut short (a crash); it was dropped
};

// Reads "PHCREC1\n" + varint-delimited RecordEntry messages. Throws
// RecordingError naming the file for a missing file, wrong magic, a first
// entry that is not a header, an unsupported format version or a record that
// does not parse; a truncated final record is dropped and flagged.
Recording read_recording(const std::filesystem::path& path);

// Frames of one instance in stream order; without `instance`, of the first
// instance that has a frame. Throws RecordingError when there are none.
std::vector<FrameState> recorded_frames(const Recording& recording, std::optional<std::uint32_t> instance,
                                        const std::string& source);

}  // namespace phasecast::client
