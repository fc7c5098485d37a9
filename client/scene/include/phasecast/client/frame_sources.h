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

// The recording's header must name the scene of `basis` with the content
// hash of the package file the bases were read from (`package_name`), so that
// q_u is only ever paired with the U_u it was synthesized for. Throws
// RecordingError naming both files otherwise (phasecast-render --replay,
// phasecast-export --recording).
void expect_recorded_with(const Recording& recording, const ClientBasis& basis,
                          const std::string& recording_name, const std::string& package_name);

struct RecordedFrames {
  std::uint32_t instance = 0;      // the instance the frames are of
  std::vector<FrameState> frames;  // in stream order
};

// Frames of one instance in stream order; without `instance`, of the first
// instance that has a frame. With `scene`, only frames of that scene count
// (a frame whose scene field is empty is taken to be of it), so an instance
// of another scene is neither the default nor accepted. Throws
// RecordingError when there are none, naming the instances there are.
RecordedFrames recorded_frames(const Recording& recording, std::optional<std::uint32_t> instance,
                               const std::string& source,
                               const std::optional<std::string>& scene = std::nullopt);

}  // namespace phasecast::client
