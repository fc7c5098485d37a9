#pragma once
// Frames without a server (local mode): the package's own phase portrait
// (one IRF played node by node) or a recording of a published stream, read
// with core::read_recording_file (docs/protocol.md "Recording").

#include "phasecast/client/frame_state.h"
#include "phasecast/core/package.h"
#include "phasecast/core/recording.h"
#include "phasecast/proto/phasecast.pb.h"

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace phasecast::client {

// The replay path names these unqualified; they are core's.
using core::Recording;
using core::RecordingError;

// The state nodes of IRF `irf` as frames 0..length-1 (q_u, q_a and, when the
// package stores it, the simulated support transform). Throws
// std::invalid_argument when `irf` is out of range.
std::vector<FrameState> portrait_frames(const core::ScenePackage& package, int irf);

FrameState frame_state(const v1::Frame& frame);

// Frames of one instance in stream order; without `instance`, of the first
// instance that has a frame. Throws RecordingError when there are none.
std::vector<FrameState> recorded_frames(const Recording& recording, std::optional<std::uint32_t> instance,
                                        const std::string& source);

}  // namespace phasecast::client
