#pragma once
// Scene health, told at once (phasecast-precompute check, docs/check.md):
// whether the settled rest is a rest, whether every moving palette entry
// followed by a quiet one returns the scene to it (a neutral mode such as a
// flag turning about its pole is named, with the rigid turn or slide that
// explains the displacement), and, given a package, how many IRFs each entry
// has and a short playback-fidelity estimate with what would improve it.
// Everything is simulated by the scene's own simulator (Blender too).

#include "phasecast/core/package.h"
#include "phasecast/precompute/pipeline/adaptive_sampling.h"
#include "phasecast/precompute/simulation/scene.h"

#include <Eigen/Core>

#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace phasecast::precompute {

struct SceneCheckOptions {
  double stop_seconds = 0;     // quiet time after each entry (0: 3 s or the quiet entry's t_max if longer)
  int fidelity_schedules = 4;  // random schedules of the fidelity estimate (with a package)
  int fidelity_items = 4;
  std::uint64_t fidelity_seed = 7;
  bool list_irfs = true;  // false: the report names only entries without an IRF (run printed the counts)
  // Thresholds, as fractions of the rest mesh's bounding radius R: a scene
  // "moves" above 0.02 R per second and "is displaced" above 0.02 R.
  double still_speed = 0.02, displaced = 0.02;
};

// The displacement of one body explained as a rigid motion (Kabsch fit).
struct RigidMotion {
  std::string body;
  double angle_deg = 0;                               // turn about `axis`
  Eigen::Vector3d axis = Eigen::Vector3d::UnitY();    // unit
  Eigen::Vector3d through = Eigen::Vector3d::Zero();  // a point on the axis (nearest the body's rest centre)
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();  // along the axis, or the slide when no turn
  double residual = 0;    // RMS (m) of what the rigid motion leaves unexplained
  double rms = 0;         // RMS displacement (m) of the body's vertices
  bool explains = false;  // a turn or slide that leaves under 30 % of the RMS unexplained
};

// A schedule from the settled rest and how far from that rest it ends.
struct RestTrial {
  std::string schedule;          // "carry 0.5; stop 3"
  double max_displacement = 0;   // m, largest vertex distance from the settled rest at the end
  double peak_displacement = 0;  // m, the same over every frame of the trial (how far it moved)
  double max_speed = 0;          // m/s, largest vertex speed at the end (support frame)
  double start_speed = 0;        // m/s, largest vertex speed at the first frame (after settle and one step)
  int worst_vertex = 0;
  std::string worst_body;
  std::optional<RigidMotion> rigid;  // the best rigid motion of the worst body, when displaced
  bool moving = false;               // still moving at the end
  bool displaced = false;            // at rest (or not), away from where it started
};

struct EntryIrfs {
  std::string entry;
  int irfs = 0;  // in the package
};

struct SceneCheck {
  std::string scene;
  double radius = 0;               // m, the rest mesh's bounding radius: the scale of the thresholds
  std::string quiet;               // the quiet palette entry the trials end with ("" : none, trials skipped)
  double stop_seconds = 0;         // how long the trials stay quiet
  std::optional<RestTrial> rest;   // the quiet entry alone: is the settled rest a rest?
  std::vector<RestTrial> returns;  // each moving entry where it moves the support (after a lead-in if
                                   // needed), then the quiet one
  std::vector<std::string> unplayable;  // moving entries no such schedule can play
  std::vector<EntryIrfs> irfs;          // with a package
  std::optional<FidelityFigures> fidelity;

  // Lines of the report, each a finding and, for a problem, what would fix it.
  std::vector<std::string> report(const SceneCheckOptions& options) const;
  int problems() const;
};

// Runs the trials (and, with `package`, the IRF counts and the fidelity
// estimate); `progress` hears ("rest trial 'carry'", done, total).
SceneCheck check_scene(
    const Scene& scene, const core::ScenePackage* package, const SceneCheckOptions& options,
    const std::function<void(const std::string& stage, int done, int total)>& progress = {});

// The rigid motion (rotation R, translation t: q = R p + t) that best takes
// `from` to `to` (N x 3 each), as a turn about an axis plus a slide along it.
RigidMotion fit_rigid_motion(const Eigen::MatrixX3d& from, const Eigen::MatrixX3d& to);

}  // namespace phasecast::precompute
