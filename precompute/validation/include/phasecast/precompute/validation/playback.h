#pragma once
// Playback fidelity (§3.5, §5): what the server plays against what the scene
// does. A schedule of palette entries is simulated with the full simulator
// (the truth) and the same entries are sent at the same frames to the real
// synthesis engine; the served shapes x-bar + U_u q_u are compared with the
// simulated ones frame by frame. This is the one room that reads both the
// offline side (simulation, sampling) and the run-time side (server).

#include "phasecast/core/package.h"
#include "phasecast/precompute/sampling/orbit_recorder.h"
#include "phasecast/precompute/sampling/palette_rules.h"
#include "phasecast/precompute/simulation/scene.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace phasecast::precompute {

// One schedule item as played: the frames it covers and how close the served
// motion is to the simulated one there. Lengths are RMS per vertex (m).
struct SegmentFigures {
  std::string entry;
  int first_frame = 0;
  int frames = 0;
  std::string refused;          // non-empty: the server refused the entry (the rule it broke)
  bool unsampled = false;       // refused because the package has no IRF of the entry at all
  double nrmse = 0;             // RMS(served - simulated) over RMS(simulated - the schedule's mean shape)
  double motion_ratio = 0;      // sum |x(f+1) - x(f)|^2, served over simulated
  double simulated_motion = 0;  // RMS per-vertex motion per frame of the simulation (m)
};

// A frame where the served IRF changes (an impulse, or an end-of-IRF rule).
struct SwitchFigures {
  int frame = 0;
  double jump = 0;  // served |x(f+1) - x(f)|, RMS per vertex (m): the new IRF shows from f + 1
  double local_motion =
      0;  // mean simulated per-frame motion over frames f-2..f+3, RMS per vertex (m), >= 0.01 mm
  double ratio() const { return jump / local_motion; }  // local_motion has a 0.01 mm floor
};

struct ScheduleFigures {
  std::string schedule;  // "open 0.8; stop 1.5; ..."
  int frames = 0;
  double nrmse = 0;
  double motion_ratio = 0;
  std::vector<SegmentFigures> segments;
  std::vector<SwitchFigures> switches;
  std::vector<double> irf_end_speeds;  // RMS vertex speed (m/s) where an IRF ended and the scene came to rest
  double median_simulated_speed = 0;   // RMS vertex speed (m/s), median over the simulated frames
  int frames_with_intersections =
      0;  // served frames with self-intersecting triangle pairs (contact_triangles: tubes left out)
  int max_intersecting_pairs = 0;
  // Per frame, RMS per-vertex distance (m) from the simulation's first frame
  // (the settled rest), served and simulated: what scripts/plot-validation draws.
  std::vector<double> served_trace;
  std::vector<double> simulated_trace;
};

struct ValidationOptions {
  bool intersections = true;  // count exact self-intersecting triangle pairs in served frames
  ProgressCallback progress;  // simulated frames done / total
};

// Plays `schedule` both ways and measures. Impulses the server refuses are
// reported in their segment (the served scene keeps doing what it did).
ScheduleFigures validate_schedule(const Scene& scene, std::shared_ptr<const core::ScenePackage> package,
                                  const std::vector<ScheduleItem>& schedule,
                                  const ValidationOptions& options = {});

// The same in two steps, so one simulation measures several packages of a
// scene: the truth of a schedule on the render surface, then each package's
// playback against it.
struct SimulatedSchedule {
  std::vector<ScheduleItem> items;
  Eigen::MatrixXd frames;  // N x 3P: the render surface's points, frame by frame
};
SimulatedSchedule simulate_truth(const Scene& scene, const std::vector<ScheduleItem>& schedule,
                                 const ProgressCallback& progress = {});
ScheduleFigures compare_playback(const Scene& scene, std::shared_ptr<const core::ScenePackage> package,
                                 const SimulatedSchedule& truth, const ValidationOptions& options = {});
// Throws, naming both (and `path`, when given), when `package` is not a
// package of `scene` (name, dt, render surface at rest): before anything is
// simulated.
void check_package_of(const Scene& scene, const core::ScenePackage& package, const std::string& path = {});

// The `index`-th random schedule of `items` entries: drawn as the sampler
// draws (palette rules, the support's range, T in (t_min, t_max) clipped to
// the range), from an independent random stream, starting from rest.
std::vector<ScheduleItem> random_schedule(const PaletteRules& rules, double frame_dt, std::uint64_t seed,
                                          int index, int items);

// Targets of the playback-fidelity issue: a moving segment moves within
// [0.67, 1.5] of the simulation; a switch jumps at most 2x the local motion.
inline constexpr double kMotionLow = 0.67, kMotionHigh = 1.5, kJumpRatio = 2.0;

// The schedule's typical simulated per-frame motion (frame-weighted mean over its segments).
double typical_motion(const ScheduleFigures& figures);
// A segment "moves" when the simulated scene moves in it at all and at least
// 10 % of the schedule's typical per-frame motion: the ones a user watches.
bool is_moving(const SegmentFigures& segment, double typical);

// Pass counts over many schedules, against the targets above.
struct ValidationSummary {
  std::vector<double> nrmse;
  int moving = 0, moving_within = 0, switches = 0, switches_within = 0, intersecting_frames = 0;

  void add(const ScheduleFigures& figures);
  double median_nrmse() const { return nrmse_percentile(0.5); }
  double p90_nrmse() const { return nrmse_percentile(0.9); }
  // Linear between ranks: the median of an even count is the mean of the middle two.
  double nrmse_percentile(double p) const;
  nlohmann::json to_json() const;
};

std::string schedule_text(const Scene& scene, const std::vector<ScheduleItem>& schedule);

nlohmann::json to_json(const ScheduleFigures& figures);

}  // namespace phasecast::precompute
