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

// Instances per FrameBatch: ids [kFrameBatchBlock * b, kFrameBatchBlock * (b + 1))
// of a scene share block b, so a block's topic stays put as instances come and go.
inline constexpr std::uint32_t kFrameBatchBlock = 1024;
inline std::uint32_t batch_block(std::uint32_t instance) {
  return instance / kFrameBatchBlock;
}
// "scene/<scene>/<block>/"; "scene/<scene>/" subscribes to every block.
std::string scene_batch_topic(const std::string& scene, std::uint32_t block);

// Starts `out` as the (empty) batch of `block` of `scene` for tick `tick`.
void begin_frame_batch(const SceneModel& scene, std::uint32_t block, std::uint64_t tick, v1::FrameBatch& out);
// Appends one instance's frame to its batch (begun for its scene and block).
void append_to_frame_batch(const SynthesizedFrame& frame, v1::FrameBatch& out);

// The Frame published for `frame` of an instance of `scene`. seq equals the
// frame number: every tick publishes every instance once, from frame 0.
void to_frame_message(const SceneModel& scene, const SynthesizedFrame& frame, v1::Frame& out);

void to_snapshot(const InstanceState& state, v1::InstanceSnapshot& out);
// Throws EngineError naming `where` when a field is out of range for the engine's types.
InstanceState from_snapshot(const v1::InstanceSnapshot& snapshot, const std::string& where);

}  // namespace phasecast::server
