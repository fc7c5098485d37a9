#pragma once
// Conversions between the synthesis engine's types and phasecast.v1 messages:
// the published Frame, its topic, and the instance snapshot of recordings.

#include "phasecast/proto/phasecast.pb.h"
#include "phasecast/server/synthesis_engine.h"

#include <cstdint>
#include <string>

namespace phasecast::server {

// "inst/<id>/": the trailing slash keeps instance 1's prefix from matching 10.
std::string instance_topic(std::uint32_t instance);

// The Frame published for `frame` of an instance of `scene`. seq equals the
// frame number: every tick publishes every instance once, from frame 0.
void to_frame_message(const SceneModel& scene, const SynthesizedFrame& frame, v1::Frame& out);

void to_snapshot(const InstanceState& state, v1::InstanceSnapshot& out);
// Throws EngineError naming `where` when a field is out of range for the engine's types.
InstanceState from_snapshot(const v1::InstanceSnapshot& snapshot, const std::string& where);

}  // namespace phasecast::server
