#pragma once
// The run-time synthesis engine (paper §5): many instances of one or several
// scenes, each either playing an IRF or at rest, advanced one frame per tick.
// Pure and deterministic: no sockets, no clocks, no threads. The same scenes
// and the same impulse schedule give bit-identical frames. docs/server.md
// describes every rule implemented here.

#include "phasecast/core/package.h"

#include <array>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace phasecast::server {

// Thrown for every refused request (unknown scene, instance or palette entry,
// forbidden transition, frame in the past): one line naming the input and what
// was expected. Nothing in the engine changed when it is thrown.
class EngineError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// A loaded scene: the package plus what the engine derives from it once.
struct SceneModel {
  std::string name;     // /attrs/scene
  std::string package;  // file name it came from (for listings and recordings)
  std::uint64_t content_hash = 0;
  std::shared_ptr<const core::ScenePackage> data;
  double blend_lambda = 1;  // eq. 12 decay rate, 1/s (package value unless overridden)
  int rest_node =
      0;  // IRF start nearest the undeformed rest shape at zero velocity (eq. 9): the settled rest
  // Where a held interaction goes on when IRF i runs out (§3.5's orbit
  // extension, chosen when the scene is loaded): step `t` > 0 of another IRF
  // `irf` of the same entry, near IRF i's last state under eq. 9 (the rule:
  // orbit_extension in synthesis_engine.cpp). irf = -1 for IRFs of entries
  // that never hold, or with no other IRF of 3 frames or more to go on in;
  // then the IRF cache's nearest start plays.
  struct Extension {
    std::int32_t irf = -1;
    std::int32_t t = 0;
  };
  std::vector<Extension> extension;  // per IRF
};

// What an instance is doing (docs/server.md, "Instance states").
enum class Mode : std::int32_t {
  rest = 0,     // holding `hold_node`, the pending blend offset decaying
  playing = 1,  // playing IRF `irf` at step `irf_t`
};

// The complete state of an instance between two ticks: enough to continue it
// exactly (recordings store it for instances that exist when recording starts).
struct InstanceState {
  Mode mode = Mode::rest;
  std::int32_t palette_index = -1;  // active palette entry; -1 at rest
  std::int32_t irf = -1;            // IRF being played; -1 at rest
  std::uint32_t irf_t = 0;          // step inside it
  std::int32_t hold_node = 0;       // node held at rest
  VectorXf offset_q_u;              // eq. 12 offset (x' - x) at blend age 0
  VectorXf offset_qdot_u;
  VectorXf offset_q_a;
  std::uint64_t blend_age = 0;        // steps since the offset was taken
  double support_s = 0;               // support coordinate (rad or m)
  std::int32_t kinematics_entry = 0;  // entry whose axis/pivot place the support
  std::int32_t jolt_entry = -1;       // entry of the running jolt; -1 none
  std::uint64_t jolt_age = 0;         // steps since the jolt started
  core::PaletteRun run;               // IRFs of one group started in a row (max_in_a_row)
};

// One synthesized frame of one instance (the content of a published Frame).
struct SynthesizedFrame {
  std::uint32_t instance = 0;
  int scene = 0;  // index into SynthesisEngine::scenes(): the Frame names its scene
  std::uint64_t frame = 0;
  VectorXf q_u;                                       // r_u (eq. 6)
  VectorXf q_a;                                       // r_a (§4.2)
  std::array<float, core::kSupportFloats> support{};  // 3x4 row-major, support -> world
  std::int32_t palette_index = -1;
  std::int32_t irf = -1;
  std::uint32_t irf_t = 0;
};

struct Instance {
  std::uint32_t id = 0;
  int scene = 0;
  std::uint64_t frame = 0;  // the next frame this instance produces
  InstanceState state;
};

// An impulse applied by a tick, in application order (recordings store these).
struct AppliedImpulse {
  std::uint32_t instance = 0;
  std::int32_t palette_index = 0;
  std::uint64_t frame = 0;
};

// A scheduled impulse the palette refused when its frame came (the instance's
// entry changed after it was accepted); `error` says why.
struct RefusedImpulse {
  std::uint32_t instance = 0;
  std::int32_t palette_index = 0;
  std::uint64_t frame = 0;
  std::string error;
};

// Everything one tick produced.
struct TickResult {
  std::vector<SynthesizedFrame> frames;  // one per instance, in increasing id order
  std::vector<AppliedImpulse> applied;
  std::vector<RefusedImpulse> refused;
};

class SynthesisEngine {
 public:
  // Adds a scene; returns its index. `blend_lambda` overrides the package's.
  // Throws EngineError if a scene of the same name is already loaded.
  int add_scene(std::shared_ptr<const core::ScenePackage> data, const std::string& package_name,
                std::uint64_t content_hash, std::optional<double> blend_lambda = std::nullopt);
  const std::vector<SceneModel>& scenes() const { return scenes_; }
  int scene_index(const std::string& name) const;  // throws EngineError for unknown names

  // A new instance of `scene` at rest at frame 0; ids start at 1, never reused.
  std::uint32_t create_instance(const std::string& scene);
  // Re-creates instance `id` exactly as it was (replaying a recording).
  void restore_instance(std::uint32_t id, const std::string& scene, std::uint64_t frame,
                        const InstanceState& state);
  void destroy_instance(std::uint32_t id);
  const Instance& instance(std::uint32_t id) const;
  const std::map<std::uint32_t, Instance>& instances() const { return instances_; }

  // Resolves a palette entry name for an instance's scene; throws EngineError.
  int palette_index(std::uint32_t instance, const std::string& name) const;
  // The palette entries the rules allow in the instance's next frame (ignoring
  // impulses already queued): what a client should offer as buttons.
  std::vector<int> allowed_entries(std::uint32_t instance) const;

  // Queues entry `palette_index` for `instance` in frame `at_frame` (default:
  // the instance's next frame). Validated now against the entry the instance
  // will have by then as far as already known (its current entry, or the last
  // impulse queued before this one); throws EngineError if refused. Returns
  // the frame it lands in.
  std::uint64_t schedule_impulse(std::uint32_t instance, int palette_index,
                                 std::optional<std::uint64_t> at_frame = std::nullopt);

  // Advances every instance by one frame, in increasing id order, and returns
  // the frames made and the impulses applied or refused. Per instance: due
  // impulses in (frame, arrival) order, then the frame is synthesized, then
  // time advances (end-of-IRF rules).
  TickResult tick();
  // The same, replacing the contents of `out`. A caller ticking in a loop
  // keeps one TickResult so the frames' q_u/q_a storage is reused instead of
  // allocated anew for every instance every tick.
  void tick(TickResult& out);

 private:
  void apply_due_impulses(Instance& inst, TickResult& out);
  void apply_impulse(Instance& inst, int entry);
  void synthesize(const Instance& inst, SynthesizedFrame& out) const;
  void advance(Instance& inst) const;

  struct Pending {
    std::uint64_t frame;
    std::uint64_t order;  // arrival order
    std::int32_t palette_index;
  };

  std::vector<SceneModel> scenes_;
  std::map<std::uint32_t, Instance> instances_;
  std::map<std::uint32_t, std::vector<Pending>> pending_;
  std::uint32_t next_id_ = 1;
  std::uint64_t next_order_ = 0;
};

// The support transform (3x4 row-major [R | t], support frame -> world) for
// coordinate `s` of kinematics `k`: rotation by s about k.axis through
// k.pivot, or translation by s along k.axis.
std::array<float, core::kSupportFloats> support_transform(const core::SupportKinematics& k, double s);

}  // namespace phasecast::server
