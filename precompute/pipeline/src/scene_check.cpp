// phasecast-precompute check: the scene's rest, its return to rest after
// each moving entry, and (with a package) IRF counts and fidelity.

#include "phasecast/precompute/pipeline/scene_check.h"

#include "phasecast/precompute/sampling/orbit_recorder.h"
#include "phasecast/precompute/sampling/palette_rules.h"
#include "phasecast/precompute/validation/playback.h"

#include <fmt/format.h>

#include <Eigen/Geometry>
#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <numbers>

namespace phasecast::precompute {
namespace {

// A turn smaller than this is a slide (its axis is noise); a rigid motion
// explains a displacement that it leaves at most this share of unexplained.
constexpr double kLeastTurnDeg = 3, kUnexplainedShare = 0.3;

// No impulse and no forcing (a jolt's pulse is alpha_I high): the scene is left alone.
bool quiet(const Scene& scene, int entry) {
  const auto& e = scene.palette[static_cast<size_t>(entry)];
  return e.alpha_impulse.isZero() && e.alpha_forcing.isZero();
}

double rest_radius(const Scene& scene) {
  const Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>> x(
      scene.model.rest.data(), scene.model.vertices(), 3);
  const Eigen::RowVector3d centre = 0.5 * (x.colwise().minCoeff() + x.colwise().maxCoeff());
  return (x.rowwise() - centre).rowwise().norm().maxCoeff();
}

Eigen::MatrixX3d frame_positions(const OrbitStore& store, int frame) {
  return store.positions.row(frame).cast<double>().reshaped<Eigen::RowMajor>(store.vertices(), 3);
}

// The largest vertex speed (m/s, support frame) of one frame.
double max_speed(const OrbitStore& store, int frame) {
  return store.velocities.row(frame)
      .cast<double>()
      .reshaped<Eigen::RowMajor>(store.vertices(), 3)
      .rowwise()
      .norm()
      .maxCoeff();
}

std::string body_of(const Scene& scene, int vertex) {
  for (const auto& b : scene.bodies) {
    if (std::find(b.vertices.begin(), b.vertices.end(), vertex) != b.vertices.end()) return b.name;
  }
  return "";
}

std::optional<RigidMotion> rigid_motion_of(const Scene& scene, const std::string& body,
                                           const Eigen::MatrixX3d& from, const Eigen::MatrixX3d& to,
                                           double displaced) {
  const auto it = std::find_if(scene.bodies.begin(), scene.bodies.end(),
                               [&](const BodyInfo& b) { return b.name == body; });
  if (it == scene.bodies.end() || it->vertices.size() < 3) return std::nullopt;
  const auto& v = it->vertices;
  RigidMotion m = fit_rigid_motion(from(v, Eigen::all), to(v, Eigen::all));
  m.body = body;
  m.explains = (m.angle_deg > kLeastTurnDeg || m.translation.norm() > displaced) &&
               m.residual <= kUnexplainedShare * m.rms;
  return m;
}

// Simulates `schedule` from the settled rest and measures its last frame
// against `rest` (the settled rest's positions).
RestTrial run_trial(const Scene& scene, const std::vector<ScheduleItem>& schedule,
                    const Eigen::MatrixX3d* rest, double radius, const SceneCheckOptions& o,
                    const ProgressCallback& progress, Eigen::MatrixX3d* first_frame = nullptr) {
  const OrbitStore store = simulate_schedule(scene, schedule, progress);
  if (first_frame) *first_frame = frame_positions(store, 0);
  const Eigen::MatrixX3d start = rest ? *rest : frame_positions(store, 0);
  const Eigen::MatrixX3d end = frame_positions(store, store.frames() - 1);
  RestTrial t;
  t.schedule = schedule_text(scene, schedule);
  const Eigen::VectorXd distance = (end - start).rowwise().norm();
  t.max_displacement = distance.maxCoeff(&t.worst_vertex);
  for (int f = 0; f < store.frames(); ++f)
    t.peak_displacement =
        std::max(t.peak_displacement, (frame_positions(store, f) - start).rowwise().norm().maxCoeff());
  t.max_speed = max_speed(store, store.frames() - 1);
  t.start_speed = max_speed(store, 0);
  t.worst_body = body_of(scene, t.worst_vertex);
  t.moving = t.max_speed > o.still_speed * radius;
  t.displaced = t.max_displacement > o.displaced * radius;
  if (t.displaced) t.rigid = rigid_motion_of(scene, t.worst_body, start, end, o.displaced * radius);
  return t;
}

// A moving entry's trial length: halfway between its shortest and longest IRF.
double trial_seconds(const PaletteEntry& e) {
  return std::clamp(0.5 * (e.t_min + e.t_max), e.t_min, e.t_max);
}

// A schedule that plays moving entry `e` where it moves the support, then the
// quiet entry: from the rest when the rules and the range allow it there,
// else after one lead-in entry and a stop (a door's 'close' needs an 'open'
// first). Empty when neither can play it.
std::vector<ScheduleItem> return_schedule(const Scene& scene, const PaletteRules& rules, int e,
                                          int quiet_entry, double stop) {
  const double dt = scene.simulation.frame_dt;
  const auto frames = [&](int entry, double at) {
    const int wanted = std::max(
        1, static_cast<int>(std::lround(trial_seconds(scene.palette[static_cast<size_t>(entry)]) / dt)));
    return std::min(wanted, rules.reachable_frames(entry, at));
  };
  if (rules.allowed_at({}, e, 0)) return {{e, frames(e, 0) * dt}, {quiet_entry, stop}};
  for (int d = 0; d < rules.size(); ++d) {
    if (d == e || d == quiet_entry || !rules.allowed_at({}, d, 0)) continue;
    const int lead = frames(d, 0);
    const double at = rules.advance(d, 0, lead);
    if (!rules.allowed_after({d}, quiet_entry) || !rules.allowed_at({d, quiet_entry}, e, at)) continue;
    return {{d, lead * dt}, {quiet_entry, stop}, {e, frames(e, at) * dt}, {quiet_entry, stop}};
  }
  return {};
}

std::string mm(double metres) {
  return metres < 0.1 ? fmt::format("{:.1f} mm", 1000 * metres) : fmt::format("{:.3f} m", metres);
}

std::string vec(const Eigen::Vector3d& v) {
  return fmt::format("({:.2f}, {:.2f}, {:.2f})", v.x(), v.y(), v.z());
}

std::string trial_line(const RestTrial& t, double seconds, const char* label) {
  const std::string where = t.worst_body.empty()
                                ? fmt::format("vertex {}", t.worst_vertex)
                                : fmt::format("vertex {} of '{}'", t.worst_vertex, t.worst_body);
  if (t.moving) {
    return fmt::format(
        "{} '{}': still moving at {}/s after {:.1f} s ({}): the server's stops end mid-motion; fix: "
        "longer quiet entries (t_min, t_max) or more damping ([simulation] mass_damping)",
        label, t.schedule, mm(t.max_speed), seconds, where);
  }
  if (!t.displaced) {
    return fmt::format("{} '{}': moved up to {}, back within {} of the settled rest, at {}/s: ok", label,
                       t.schedule, mm(t.peak_displacement), mm(t.max_displacement), mm(t.max_speed));
  }
  std::string mode = "the scene settles into another shape";
  if (t.rigid && !t.rigid->explains) {
    mode += fmt::format(
        " (no rigid motion of '{}' explains it: the best turns {:.0f} deg and leaves {} of {} RMS)",
        t.rigid->body, t.rigid->angle_deg, mm(t.rigid->residual), mm(t.rigid->rms));
  } else if (t.rigid && t.rigid->angle_deg > kLeastTurnDeg) {
    mode = fmt::format("a neutral mode: '{}' turned {:.0f} deg about {} through {} and stays there",
                       t.rigid->body, t.rigid->angle_deg, vec(t.rigid->axis), vec(t.rigid->through));
  } else if (t.rigid) {
    mode = fmt::format("a neutral mode: '{}' slid by {} and stays there", t.rigid->body,
                       vec(t.rigid->translation));
  }
  return fmt::format(
      "{} '{}': comes to rest {} from the settled rest ({}, at {}/s): {}; the served scene has one rest, so "
      "it snaps back to it. Fix: pin vertices off that axis or add a brace against the motion, stiffen it "
      "(bending, young), or give the scene a rest it returns to (settle, gravity across the free motion)",
      label, t.schedule, mm(t.max_displacement), where, mm(t.max_speed), mode);
}

}  // namespace

RigidMotion fit_rigid_motion(const Eigen::MatrixX3d& from, const Eigen::MatrixX3d& to) {
  const Eigen::RowVector3d pc = from.colwise().mean(), qc = to.colwise().mean();
  const Eigen::MatrixX3d P = from.rowwise() - pc, Q = to.rowwise() - qc;
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(P.transpose() * Q, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d D = Eigen::Matrix3d::Identity();
  D(2, 2) = (svd.matrixV() * svd.matrixU().transpose()).determinant() < 0 ? -1 : 1;
  const Eigen::Matrix3d R = svd.matrixV() * D * svd.matrixU().transpose();
  const Eigen::Vector3d t = qc.transpose() - R * pc.transpose();
  RigidMotion m;
  const Eigen::AngleAxisd turn(R);
  m.angle_deg = turn.angle() * 180 / std::numbers::pi;
  m.axis = turn.axis();
  m.rms = std::sqrt((to - from).rowwise().squaredNorm().mean());
  const Eigen::MatrixX3d fitted = (from * R.transpose()).rowwise() + t.transpose();
  m.residual = std::sqrt((fitted - to).rowwise().squaredNorm().mean());
  if (m.angle_deg > kLeastTurnDeg) {
    // q = R (p - c) + c + s a: s from t along a, c from the rest (min-norm, so across a).
    const double s = m.axis.dot(t);
    const Eigen::Vector3d c = (Eigen::Matrix3d::Identity() - R)
                                  .jacobiSvd(Eigen::ComputeFullU | Eigen::ComputeFullV)
                                  .solve(t - s * m.axis);
    m.through = c + m.axis.dot(pc.transpose() - c) * m.axis;
    m.translation = s * m.axis;
  } else {
    // Below a noticeable turn the axis is noise: a slide of the centroid.
    m.translation = (qc - pc).transpose();
    m.through = pc.transpose();
  }
  return m;
}

SceneCheck check_scene(const Scene& scene, const core::ScenePackage* package, const SceneCheckOptions& o,
                       const std::function<void(const std::string&, int, int)>& progress) {
  SceneCheck c;
  c.scene = scene.name;
  c.radius = rest_radius(scene);
  int quiet_entry = -1;
  for (int d = 0; d < static_cast<int>(scene.palette.size()) && quiet_entry < 0; ++d) {
    if (quiet(scene, d)) quiet_entry = d;
  }
  const auto stage = [&progress](const std::string& name) -> ProgressCallback {
    return [&progress, name](int done, int total) {
      if (progress) progress(name, done, total);
    };
  };
  if (quiet_entry >= 0) {
    const auto& q = scene.palette[static_cast<size_t>(quiet_entry)];
    c.quiet = q.name;
    const double stop = c.stop_seconds = o.stop_seconds > 0 ? o.stop_seconds : std::max(3.0, q.t_max);
    Eigen::MatrixX3d rest;
    c.rest = run_trial(scene, {{quiet_entry, stop}}, nullptr, c.radius, o, stage("rest trial"), &rest);
    const PaletteRules rules = make_palette_rules(scene);
    for (int d = 0; d < static_cast<int>(scene.palette.size()); ++d) {
      if (d == quiet_entry || quiet(scene, d)) continue;
      const auto& e = scene.palette[static_cast<size_t>(d)];
      const auto schedule = return_schedule(scene, rules, d, quiet_entry, stop);
      if (schedule.empty()) {
        c.unplayable.push_back(e.name);
        continue;
      }
      c.returns.push_back(
          run_trial(scene, schedule, &rest, c.radius, o, stage(fmt::format("return trial '{}'", e.name))));
    }
  } else {
    // Jolts (no forcing) leave the scene alone once their pulse is over: each
    // is its own quiet time, measured against its own first frame.
    const double stop = c.stop_seconds = o.stop_seconds > 0 ? o.stop_seconds : 3.0;
    for (int d = 0; d < static_cast<int>(scene.palette.size()); ++d) {
      const auto& e = scene.palette[static_cast<size_t>(d)];
      if (!e.alpha_forcing.isZero()) continue;
      c.returns.push_back(run_trial(scene, {{d, trial_seconds(e) + stop}}, nullptr, c.radius, o,
                                    stage(fmt::format("return trial '{}'", e.name))));
    }
  }
  if (package) {
    for (const auto& e : scene.palette) c.irfs.push_back({e.name, 0});
    for (const auto entry : package->portrait.irf_palette) {
      if (entry >= 0 && static_cast<size_t>(entry) < c.irfs.size()) ++c.irfs[static_cast<size_t>(entry)].irfs;
    }
    const bool playable =
        std::none_of(c.irfs.begin(), c.irfs.end(), [](const EntryIrfs& e) { return e.irfs == 0; });
    if (o.fidelity_schedules > 0 && playable) {  // random schedules would play entries the server refuses
      c.fidelity = measure_fidelity(scene, *package, o.fidelity_seed, o.fidelity_schedules, o.fidelity_items,
                                    stage("fidelity estimate"));
    }
  }
  return c;
}

int SceneCheck::problems() const {
  int n = 0;
  if (rest && (rest->moving || rest->displaced)) ++n;
  for (const auto& t : returns) n += (t.moving || t.displaced) ? 1 : 0;
  for (const auto& e : irfs) n += e.irfs == 0 ? 1 : 0;
  return n;
}

std::vector<std::string> SceneCheck::report(const SceneCheckOptions& o) const {
  std::vector<std::string> lines;
  lines.push_back(fmt::format("scene '{}': rest mesh radius {}; moving above {}/s, displaced above {}", scene,
                              mm(radius), mm(o.still_speed * radius), mm(o.displaced * radius)));
  if (quiet.empty()) {
    lines.push_back(fmt::format(
        "no quiet palette entry (zero alpha_impulse and alpha_forcing): the rest is not checked{}; add a "
        "'stop' entry",
        returns.empty() ? ", nor the return to it"
                        : ", the jolts (no forcing) are each followed by their own quiet"));
  } else {
    const std::string label = fmt::format("rest (settled, first frame at {}/s):", mm(rest->start_speed));
    lines.push_back(trial_line(*rest, stop_seconds, label.c_str()));
  }
  for (const auto& t : returns) lines.push_back(trial_line(t, stop_seconds, "return:"));
  for (const auto& name : unplayable) {
    lines.push_back(
        fmt::format("return: '{}' moves nothing from the rest, nor after one entry and '{}' (its "
                    "rules or the support's range): not checked",
                    name, quiet));
  }
  for (const auto& e : irfs) {
    if (e.irfs > 0 && !o.list_irfs) continue;
    lines.push_back(e.irfs > 0 ? fmt::format("palette '{}': {} IRF{} in the package", e.entry, e.irfs,
                                             e.irfs > 1 ? "s" : "")
                               : fmt::format("palette '{}': no IRF in the package, so the server refuses it; "
                                             "fix: sample more (--irfs-per-chain, --chains) or let it follow "
                                             "more entries (its `after`)",
                                             e.entry));
  }
  if (!fidelity && o.fidelity_schedules > 0 &&
      std::any_of(irfs.begin(), irfs.end(), [](const EntryIrfs& e) { return e.irfs == 0; })) {
    lines.push_back(
        "fidelity: not estimated (random schedules would play the entries above that have no IRF)");
  }
  if (fidelity) {
    const auto& f = *fidelity;
    const FidelityTarget target;
    std::string suggestion = "meets the default target";
    if (!f.meets(target)) {
      suggestion = f.moving_in_range() < target.moving_in_range
                       ? "below the default target; motion parts from the simulation: more IRFs "
                         "(--irfs-per-chain, or --until-fidelity 0.15)"
                       : "below the default target; more IRFs (--irfs-per-chain), or longer quiet entries "
                         "if the stops freeze mid-motion";
    }
    lines.push_back(fmt::format(
        "fidelity ({} random schedules of {} entries, seed {}): median NRMSE {:.3f}, 90th percentile {:.3f}, "
        "{}/{} moving segments within [0.67, 1.5]: {}",
        f.schedules, f.items, f.seed, f.median_nrmse, f.p90_nrmse, f.moving_within, f.moving, suggestion));
  }
  return lines;
}

}  // namespace phasecast::precompute
