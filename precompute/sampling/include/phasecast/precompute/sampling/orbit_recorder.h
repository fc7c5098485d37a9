#pragma once
// Drives a Simulator through a sequence of palette entries and records the
// orbit: one IRF per entry, frame 0 being the state right after the entry's
// impulse, one frame per frame_dt after that. The state after an IRF's last
// step is where the next IRF's impulse is applied.

#include "phasecast/precompute/sampling/orbit_store.h"
#include "phasecast/precompute/simulation/scene.h"
#include "phasecast/precompute/simulation/simulator.h"

#include <functional>
#include <string>
#include <vector>

namespace phasecast::precompute {

struct ScheduleItem {
  int entry = 0;
  double duration = 0;  // s
};

// Frames a schedule item of `seconds` lasts at `frame_dt` (rounded to the nearest).
int schedule_frames(double seconds, double frame_dt);

// Parses "open 1.5; stop 2; close 1.5" (entry name, duration in seconds).
// Throws SceneError naming the schedule item for unknown names or bad durations.
std::vector<ScheduleItem> parse_schedule(const std::string& text, const Scene& scene);

// Called after each simulated frame with (frames done, frames total).
using ProgressCallback = std::function<void(int, int)>;

// A store holding the scene's mesh and palette and no frames yet.
OrbitStore empty_orbit_store(const Scene& scene);

// Simulates one IRF of `frames` frames from the simulator's current state
// into `out` (resized to the IRF: a sampling chain reuses one buffer, so it
// holds one IRF whatever its length); `on_frame` runs after every simulated
// frame. `continues`: the simulator was not reset since the previous IRF.
void record_irf_frames(Simulator& simulator, const Scene& scene, int entry, int frames, bool continues,
                       IrfFrames& out, const std::function<void()>& on_frame = {});

// record_irf_frames, appended to `store` (`continues` is ignored for its first IRF).
void record_irf(Simulator& simulator, const Scene& scene, int entry, int frames, OrbitStore& store,
                const std::function<void()>& on_frame = {}, bool continues = true);

// Relaxes the simulator towards static equilibrium under gravity with the
// support at rest: `seconds / frame_dt` steps, each followed by zeroing the
// velocities, so every step is a damped Newton move towards equilibrium
// (a toy sags onto its base instead of bouncing at the start of the first IRF).
void settle(Simulator& simulator, double seconds);

// The rest state settled for the scene's simulation.settle seconds: where
// sampled chains, simulated schedules and (through its rest node) the server start.
SimState settled_rest_state(const Scene& scene, Simulator& simulator);

// Runs the schedule from the rest state, settled for the scene's simulation.settle seconds.
OrbitStore simulate_schedule(const Scene& scene, const std::vector<ScheduleItem>& schedule,
                             const ProgressCallback& progress = {});

}  // namespace phasecast::precompute
