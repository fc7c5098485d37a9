#include "phasecast/server/synthesis_engine.h"

#include "phasecast/core/phase_space.h"

#include <fmt/format.h>

#include <Eigen/Cholesky>

#include <algorithm>
#include <cmath>
#include <limits>
#include <ranges>

namespace phasecast::server {
namespace {

constexpr std::size_t kMaxPendingPerInstance = 1024;  // bounds what a flood of impulses can queue
constexpr double kJoltEndTaus = 20;                   // a jolt is over after 20 time constants

// Full state x = (q_u, qdot_u, q_a) of an instance at some frame (eq. 12's x').
struct PhaseState {
  VectorXf q_u, qdot_u, q_a;
};

std::size_t at(int i) {
  return static_cast<std::size_t>(i);
}

std::string describe(const SceneModel& s, std::uint32_t id) {
  return fmt::format("instance {} ({})", id, s.name);
}

std::string entry_name(const core::ImpulsePalette& p, int i) {
  return i < 0 ? "rest" : p.names[at(i)];
}

std::string allowed_after(const core::ImpulsePalette& p, int from) {
  std::string list;
  for (int d = 0; d < p.size(); ++d) {
    if (p.allowed(from, d)) list += (list.empty() ? "" : ", ") + p.names[at(d)];
  }
  return list.empty() ? "none" : list;
}

std::string transition_error(const core::ImpulsePalette& p, int from, int to) {
  return fmt::format("'{}' is not allowed {} '{}' (allowed: {})", p.names[at(to)],
                     from < 0 ? "from" : "after", entry_name(p, from), allowed_after(p, from));
}

// Eq. 12 weight e^(-lambda t) after `age` steps.
float blend_weight(const SceneModel& s, std::uint64_t age) {
  return static_cast<float>(std::exp(-s.blend_lambda * static_cast<double>(age) * s.data->attributes.dt));
}

// The state node the instance is at (the row of /portrait/nearest_irf to use, §5.2).
int current_node(const SceneModel& s, const InstanceState& st) {
  if (st.mode == Mode::rest) return st.hold_node;
  const auto& pp = s.data->portrait;
  const int len = pp.irf_length[at(st.irf)];
  return pp.irf_start[at(st.irf)] + std::min(static_cast<int>(st.irf_t), len - 1);
}

std::string group_names(const core::ImpulsePalette& p, int d) {
  std::string list;
  for (int e = 0; e < p.size(); ++e) {
    if (p.group[at(e)] == p.group[at(d)]) list += (list.empty() ? "'" : "', '") + p.names[at(e)];
  }
  return list + "'";
}

// Why the palette's rules (the state machine of /palette: transitions after
// `from`, the group run, the support's range at coordinate `s` when known)
// forbid entry `d`, or nullopt. The sampler drew its orbits under the same
// rules (PaletteRules), so what they forbid was never sampled.
std::optional<std::string> rule_refusal(const SceneModel& s, int from, const core::PaletteRun& run,
                                        std::optional<double> support_s, int d) {
  const auto& pal = s.data->palette;
  if (!pal.allowed(from, d)) return transition_error(pal, from, d);
  if (!pal.within_run_limit(run, d)) {
    return fmt::format("'{}' is not allowed: {} IRFs of {} already in a row (rule max_in_a_row = {})",
                       pal.names[at(d)], run.length, group_names(pal, d), pal.max_in_a_row[at(d)]);
  }
  if (support_s && !pal.can_move_support(d, *support_s, s.data->attributes.dt)) {
    const auto& k = pal.kinematics[at(d)];
    return fmt::format(
        "'{}' cannot move the support: s = {:.4g} is at the end of its range [{:.4g}, {:.4g}] (rule: "
        "support range)",
        pal.names[at(d)], *support_s, k.range_min, k.range_max);
  }
  return std::nullopt;
}

// Why entry `d` cannot start in the instance's current frame, or nullopt if
// it can. Checked again when the frame comes: an impulse queued for a later
// frame was validated against the entry expected then, which an end-of-IRF
// rule may have changed, and the node it lands on was not known.
std::optional<std::string> refusal(const SceneModel& s, const InstanceState& st, int d) {
  if (auto why = rule_refusal(s, st.palette_index, st.run, st.support_s, d)) return why;
  const int node = current_node(s, st);
  if (s.data->portrait.nearest_irf(node, d) < 0) {
    return fmt::format("no IRF of '{}' is cached at state node {} (/portrait/nearest_irf)",
                       s.data->palette.names[at(d)], node);
  }
  return std::nullopt;
}

// x' at the instance's current position: the node's state plus the decayed
// offset (eq. 12). At rest the held node has zero velocity. Past the end of
// an IRF the last node is extrapolated by one step of its velocity.
PhaseState state_now(const SceneModel& s, const InstanceState& st) {
  const auto& pp = s.data->portrait;
  const int node = current_node(s, st);
  const float w = blend_weight(s, st.blend_age);
  PhaseState x;
  x.q_u = pp.q_u.row(node).transpose() + w * st.offset_q_u;
  x.q_a = pp.q_a.row(node).transpose() + w * st.offset_q_a;
  x.qdot_u = w * st.offset_qdot_u;
  if (st.mode == Mode::playing) {
    x.qdot_u += pp.qdot_u.row(node).transpose();
    if (static_cast<int>(st.irf_t) >= pp.irf_length[at(st.irf)]) {
      x.q_u += static_cast<float>(s.data->attributes.dt) * pp.qdot_u.row(node).transpose();
    }
  }
  return x;
}

// Plays IRF `irf` of entry `entry` from its step `t` (0: its start) and state
// x' (eq. 12: offset x' - x_node, decaying from then on).
void start_irf(const SceneModel& s, InstanceState& st, int entry, int irf, const PhaseState& x, int t = 0) {
  const auto& pp = s.data->portrait;
  const int start = pp.irf_start[at(irf)] + t;
  st.mode = Mode::playing;
  st.palette_index = entry;
  st.irf = irf;
  st.irf_t = static_cast<std::uint32_t>(t);
  st.offset_q_u = x.q_u - pp.q_u.row(start).transpose();
  st.offset_qdot_u = x.qdot_u - pp.qdot_u.row(start).transpose();
  st.offset_q_a = x.q_a - pp.q_a.row(start).transpose();
  st.blend_age = 0;
  const auto& k = s.data->palette.kinematics[at(entry)];
  if (k.pulse_tau > 0) {
    st.jolt_entry = entry;
    st.jolt_age = 0;
  } else {
    st.kinematics_entry = entry;
  }
}

// Comes to rest holding the last node played; the pending offset keeps decaying.
void come_to_rest(const SceneModel& s, InstanceState& st) {
  st.hold_node = current_node(s, st);
  st.mode = Mode::rest;
  st.palette_index = -1;
  st.irf = -1;
  st.irf_t = 0;
}

// End of the IRF of entry d (/palette/on_end): rest, or continue blended on
// the follow-up entry's nearest IRF, or (hold: the forcing persists) at the
// IRF's orbit extension, a node inside another IRF of the same entry.
void end_of_irf(const SceneModel& s, InstanceState& st, std::int32_t rule) {
  const int d = st.palette_index;
  const auto& extension = s.extension[at(st.irf)];
  if (rule == core::kEndHold && extension.irf >= 0) {
    start_irf(s, st, d, extension.irf, state_now(s, st), extension.t);
    return;
  }
  const int next = rule == core::kEndHold ? d : rule;
  const int irf = next >= 0 ? s.data->portrait.nearest_irf(current_node(s, st), next) : -1;
  if (irf < 0) {
    come_to_rest(s, st);
    return;
  }
  // A follow-up starts an IRF of its own (the sampler's history has it); a
  // held entry continues the one it is in.
  if (rule >= 0) st.run = s.data->palette.extended(st.run, next);
  start_irf(s, st, next, irf, state_now(s, st));
}

// Whether the entry drives a limited support at a steady rate (not a jolt;
// range min == max means unlimited).
bool drives_limited_support(const core::SupportKinematics& k) {
  return k.pulse_tau == 0 && k.rate != 0 && k.range_max > k.range_min;
}

// Whether the support coordinate has reached the end of its range in the
// direction the active entry drives it (the door stops at its 90 degrees).
bool range_reached(const core::SupportKinematics& k, double s) {
  if (!drives_limited_support(k)) return false;
  return k.rate > 0 ? s >= k.range_max : s <= k.range_min;
}

// Whether the entry moves a limited support that has not reached the end of
// its range in the entry's direction.
bool drives_within_range(const core::SupportKinematics& k, double s) {
  return drives_limited_support(k) && !range_reached(k, s);
}

// Whether IRFs of entry d may run out while the interaction persists: it
// holds (on_end), or it drives a limited support, which the instance keeps
// driving until the range ends.
bool may_hold(const core::ImpulsePalette& p, int d) {
  return p.on_end[at(d)] == core::kEndHold || drives_limited_support(p.kinematics[at(d)]);
}

// Frames an orbit extension leaves at least, so that it is not itself over at once.
constexpr int kMinExtensionFrames = 2;

// Orbit extension of IRF i (§3.5: orbits "terminating close enough ... to be
// smoothly blended to other orbits ... can be extended"), from the state
// end_of_irf blends from: the last node one step on. Of each other IRF of the
// entry, its node nearest that state under eq. 9, past its start (a start
// holds the velocity before the impulse: playing on from it is the onset
// again) and with kMinExtensionFrames left. Of those IRFs' nodes within
// kSameStateFraction of the portrait's radius of the nearest, the one with
// the most frames left, then the nearest, then the lowest IRF: the cache's
// rule, across IRFs, so that the extension never rewinds along one orbit.
SceneModel::Extension orbit_extension(const core::ScenePackage& pkg, int i, double band) {
  const auto& pp = pkg.portrait;
  const int last = pp.irf_start[at(i)] + pp.irf_length[at(i)] - 1;
  const VectorXf qdot = pp.qdot_u.row(last).transpose();
  const VectorXf q = pp.q_u.row(last).transpose() + static_cast<float>(pkg.attributes.dt) * qdot;
  struct Candidate {
    SceneModel::Extension at;
    double distance = std::numeric_limits<double>::infinity();
  };
  std::vector<Candidate> nearest_of_each;
  for (int j = 0; j < pp.irf_count(); ++j) {
    if (j == i || pp.irf_palette[at(j)] != pp.irf_palette[at(i)]) continue;
    Candidate c;
    for (int t = 1; t + kMinExtensionFrames <= pp.irf_length[at(j)]; ++t) {
      const int node = pp.irf_start[at(j)] + t;
      const double d = core::phase_distance_squared(q, qdot, pp.q_u.row(node).transpose(),
                                                    pp.qdot_u.row(node).transpose(), pkg.attributes.beta);
      if (d < c.distance) c = {{j, t}, d};
    }
    if (c.at.irf >= 0) nearest_of_each.push_back(c);
  }
  if (nearest_of_each.empty()) return {};
  const double nearest = std::ranges::min(nearest_of_each, {}, &Candidate::distance).distance;
  const double reach = std::sqrt(nearest) + band;
  const auto left = [&](const Candidate& c) { return pp.irf_length[at(c.at.irf)] - c.at.t; };
  const Candidate* best = nullptr;
  for (const auto& c : nearest_of_each) {
    if (std::sqrt(c.distance) > reach) continue;
    if (!best || left(c) > left(*best) || (left(c) == left(*best) && c.distance < best->distance)) best = &c;
  }
  return best->at;
}

std::vector<SceneModel::Extension> orbit_extensions(const core::ScenePackage& pkg) {
  const auto& pp = pkg.portrait;
  const Eigen::VectorXd radius_squared =
      pp.q_u.cast<double>().rowwise().squaredNorm() +
      pkg.attributes.beta * pp.qdot_u.cast<double>().rowwise().squaredNorm();
  const double radius = radius_squared.size() ? std::sqrt(radius_squared.maxCoeff()) : 0.0;
  const double band = core::kSameStateFraction * radius;
  std::vector<SceneModel::Extension> extensions(at(pp.irf_count()));
  for (int i = 0; i < pp.irf_count(); ++i) {
    if (may_hold(pkg.palette, pp.irf_palette[at(i)])) extensions[at(i)] = orbit_extension(pkg, i, band);
  }
  return extensions;
}

// Displacement pulse of a jolt (pulse_tau > 0): rate * tau e^(-tau / pulse_tau),
// leaving rest at `rate` and returning to rest, peak rate * pulse_tau / e.
double jolt_pulse(const core::SupportKinematics& k, double time) {
  return k.rate * time * std::exp(-time / k.pulse_tau);
}

using Transform = std::array<float, core::kSupportFloats>;

// a ∘ b for 3x4 row-major [R | t] transforms.
Transform compose(const Transform& a, const Transform& b) {
  Transform c{};
  for (int r = 0; r < 3; ++r) {
    for (int col = 0; col < 4; ++col) {
      float v = col == 3 ? a[at(4 * r + 3)] : 0.0f;
      for (int k = 0; k < 3; ++k) v += a[at(4 * r + k)] * b[at(4 * k + col)];
      c[at(4 * r + col)] = v;
    }
  }
  return c;
}

}  // namespace

Transform support_transform(const core::SupportKinematics& k, double s) {
  Transform m{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};
  const double ax = k.axis[0], ay = k.axis[1], az = k.axis[2];
  if (!k.rotational) {
    m[3] = static_cast<float>(ax * s);
    m[7] = static_cast<float>(ay * s);
    m[11] = static_cast<float>(az * s);
    return m;
  }
  // Rodrigues' formula; t = p - R p keeps the pivot fixed.
  const double c = std::cos(s), si = std::sin(s), C = 1 - c;
  const double R[3][3] = {{c + ax * ax * C, ax * ay * C - az * si, ax * az * C + ay * si},
                          {ay * ax * C + az * si, c + ay * ay * C, ay * az * C - ax * si},
                          {az * ax * C - ay * si, az * ay * C + ax * si, c + az * az * C}};
  for (int r = 0; r < 3; ++r) {
    double t = k.pivot[at(r)];
    for (int col = 0; col < 3; ++col) {
      m[at(4 * r + col)] = static_cast<float>(R[r][col]);
      t -= R[r][col] * k.pivot[at(col)];
    }
    m[at(4 * r + 3)] = static_cast<float>(t);
  }
  return m;
}

int SynthesisEngine::add_scene(std::shared_ptr<const core::ScenePackage> data,
                               const std::string& package_name, std::uint64_t content_hash,
                               std::optional<double> blend_lambda) {
  const std::string& name = data->attributes.scene;
  for (const auto& s : scenes_) {
    if (s.name == name) {
      throw EngineError(
          fmt::format("scene '{}' of {} is already loaded from {} (expected unique scene names)", name,
                      package_name, s.package));
    }
  }
  const double lambda = blend_lambda.value_or(data->attributes.blend_lambda);
  if (!std::isfinite(lambda) || lambda < 0) {
    throw EngineError(
        fmt::format("blend lambda {} for scene '{}' (expected a finite value >= 0)", lambda, name));
  }
  SceneModel s;
  s.name = name;
  s.package = package_name;
  s.content_hash = content_hash;
  s.blend_lambda = lambda;
  // The undeformed rest shape in reduced coordinates: the least-squares q with
  // U_u q = x_rest - x-bar. U_u^T U_u is not the identity once sheets' back
  // sides repeat rows or render points are embedded (rows W U_u), so the
  // normal equations are solved (r_u x r_u, in double).
  const auto& m = data->mesh;
  const Eigen::Map<const VectorXf> rest(m.rest_positions.data(), 3 * m.rest_positions.rows());
  const Eigen::MatrixXd U = data->reduction.U_u.cast<double>();
  const Eigen::VectorXd offset = (rest - data->reduction.mean_shape).cast<double>();
  const VectorXf q_rest = (U.transpose() * U).ldlt().solve(U.transpose() * offset).cast<float>();
  const auto& pp = data->portrait;
  double best = std::numeric_limits<double>::infinity();
  // Among IRF starts only: chains start from the settled rest (a cloth sagged
  // under gravity), so the start nearest the undeformed shape is that state,
  // where the simulation a user compares with begins too.
  for (const int n : pp.irf_start) {
    const double d =
        core::phase_distance_squared(pp.q_u.row(n).transpose(), pp.qdot_u.row(n).transpose(), q_rest,
                                     VectorXf::Zero(q_rest.size()), data->attributes.beta);
    if (d < best) {
      best = d;
      s.rest_node = n;
    }
  }
  s.extension = orbit_extensions(*data);
  s.data = std::move(data);
  scenes_.push_back(std::move(s));
  return static_cast<int>(scenes_.size()) - 1;
}

int SynthesisEngine::scene_index(const std::string& name) const {
  std::string known;
  for (std::size_t i = 0; i < scenes_.size(); ++i) {
    if (scenes_[i].name == name) return static_cast<int>(i);
    known += (known.empty() ? "" : ", ") + scenes_[i].name;
  }
  throw EngineError(fmt::format("unknown scene '{}' (expected one of {})", name, known));
}

std::uint32_t SynthesisEngine::create_instance(const std::string& scene) {
  const int si = scene_index(scene);
  const SceneModel& s = scenes_[at(si)];
  InstanceState st;
  st.hold_node = s.rest_node;
  st.offset_q_u = VectorXf::Zero(s.data->rank_u());
  st.offset_qdot_u = VectorXf::Zero(s.data->rank_u());
  st.offset_q_a = VectorXf::Zero(s.data->rank_a());
  const auto& k0 = s.data->palette.kinematics[0];
  st.support_s = std::clamp(0.0, static_cast<double>(k0.range_min), static_cast<double>(k0.range_max));
  const std::uint32_t id = next_id_;
  restore_instance(id, scene, 0, st);
  return id;
}

void SynthesisEngine::restore_instance(std::uint32_t id, const std::string& scene, std::uint64_t frame,
                                       const InstanceState& state) {
  const int si = scene_index(scene);
  const auto& pkg = *scenes_[at(si)].data;
  if (id == 0 || instances_.count(id)) {
    throw EngineError(fmt::format("instance {}: id already in use or 0 (expected a new id)", id));
  }
  const auto& pp = pkg.portrait;
  const bool playing = state.mode == Mode::playing;
  const bool bad =
      (playing && (state.irf < 0 || state.irf >= pp.irf_count() ||
                   static_cast<int>(state.irf_t) >= pp.irf_length[at(state.irf)] || state.palette_index < 0 ||
                   state.palette_index >= pkg.palette.size())) ||
      (!playing && (state.mode != Mode::rest || state.palette_index != -1 || state.irf != -1)) ||
      state.hold_node < 0 || state.hold_node >= pp.nodes() || state.offset_q_u.size() != pkg.rank_u() ||
      state.offset_qdot_u.size() != pkg.rank_u() || state.offset_q_a.size() != pkg.rank_a() ||
      state.kinematics_entry < 0 || state.kinematics_entry >= pkg.palette.size() || state.jolt_entry < -1 ||
      state.jolt_entry >= pkg.palette.size() || !std::isfinite(state.support_s) || state.run.group < 0 ||
      state.run.group >= pkg.palette.size() || !state.offset_q_u.allFinite() ||
      !state.offset_qdot_u.allFinite() || !state.offset_q_a.allFinite();
  if (bad) {
    throw EngineError(
        fmt::format("instance {} ({}): inconsistent state (expected IRF, node and entry indices and offset "
                    "sizes r_u = {}, r_a = {} of this scene)",
                    id, scene, pkg.rank_u(), pkg.rank_a()));
  }
  Instance inst;
  inst.id = id;
  inst.scene = si;
  inst.frame = frame;
  inst.state = state;
  instances_.emplace(id, std::move(inst));
  next_id_ = std::max(next_id_, id + 1);
}

void SynthesisEngine::destroy_instance(std::uint32_t id) {
  (void)instance(id);
  instances_.erase(id);
  pending_.erase(id);
}

const Instance& SynthesisEngine::instance(std::uint32_t id) const {
  const auto it = instances_.find(id);
  if (it == instances_.end()) {
    throw EngineError(fmt::format("unknown instance {} (expected one of the {} existing instances)", id,
                                  instances_.size()));
  }
  return it->second;
}

int SynthesisEngine::palette_index(std::uint32_t id, const std::string& name) const {
  const Instance& inst = instance(id);
  const auto& s = scenes_[at(inst.scene)];
  const auto& names = s.data->palette.names;
  const int d = s.data->palette.index_of(name);
  if (d < 0) {
    std::string list;
    for (const auto& n : names) list += (list.empty() ? "" : ", ") + n;
    throw EngineError(
        fmt::format("{}: unknown palette entry '{}' (expected one of {})", describe(s, id), name, list));
  }
  return d;
}

std::vector<int> SynthesisEngine::allowed_entries(std::uint32_t id) const {
  const Instance& inst = instance(id);
  const SceneModel& s = scenes_[at(inst.scene)];
  std::vector<int> out;
  for (int d = 0; d < s.data->palette.size(); ++d) {
    if (!refusal(s, inst.state, d)) out.push_back(d);
  }
  return out;
}

std::uint64_t SynthesisEngine::schedule_impulse(std::uint32_t id, int d,
                                                std::optional<std::uint64_t> at_frame) {
  const Instance& inst = instance(id);
  const SceneModel& s = scenes_[at(inst.scene)];
  const auto& pal = s.data->palette;
  if (d < 0 || d >= pal.size()) {
    throw EngineError(fmt::format("{}: palette index {} out of range (expected 0..{})", describe(s, id), d,
                                  pal.size() - 1));
  }
  const std::uint64_t frame = at_frame.value_or(inst.frame);
  if (frame < inst.frame) {
    throw EngineError(fmt::format("{}: frame {} is in the past (expected at least the next frame {})",
                                  describe(s, id), frame, inst.frame));
  }
  auto& queue = pending_[id];
  if (queue.size() >= kMaxPendingPerInstance) {
    throw EngineError(fmt::format("{}: {} impulses already pending (expected at most {} queued)",
                                  describe(s, id), queue.size(), kMaxPendingPerInstance));
  }
  // The entry and run the instance will have by then, as far as already
  // known; the support's coordinate is known only for its next frame.
  int from = inst.state.palette_index;
  core::PaletteRun run = inst.state.run;
  bool known_support = frame == inst.frame;
  for (const auto& p : queue) {
    if (p.frame > frame) continue;
    from = p.palette_index;
    run = pal.extended(run, p.palette_index);
    known_support = false;
  }
  const auto& irf_palette = s.data->portrait.irf_palette;
  if (std::find(irf_palette.begin(), irf_palette.end(), d) == irf_palette.end()) {
    throw EngineError(fmt::format("{}: palette entry '{}' has no sampled IRF (expected an entry with IRFs)",
                                  describe(s, id), pal.names[at(d)]));
  }
  const auto support = known_support ? std::optional<double>(inst.state.support_s) : std::nullopt;
  if (auto why = rule_refusal(s, from, run, support, d))
    throw EngineError(fmt::format("{}: {}", describe(s, id), *why));
  const Pending p{frame, next_order_++, d};
  const auto pos = std::upper_bound(queue.begin(), queue.end(), p, [](const Pending& a, const Pending& b) {
    return a.frame != b.frame ? a.frame < b.frame : a.order < b.order;
  });
  queue.insert(pos, p);
  return frame;
}

void SynthesisEngine::apply_impulse(Instance& inst, int d) {
  const SceneModel& s = scenes_[at(inst.scene)];
  const int irf = s.data->portrait.nearest_irf(current_node(s, inst.state), d);  // §5.2 cache
  inst.state.run = s.data->palette.extended(inst.state.run, d);
  start_irf(s, inst.state, d, irf, state_now(s, inst.state));
}

// Writes every field of `f`; q_u and q_a keep their storage when `f` held a
// frame of the same ranks (Eigen resizes them otherwise).
void SynthesisEngine::synthesize(const Instance& inst, SynthesizedFrame& f) const {
  const SceneModel& s = scenes_[at(inst.scene)];
  const auto& pkg = *s.data;
  const InstanceState& st = inst.state;
  const int node = current_node(s, st);
  const float w = blend_weight(s, st.blend_age);
  f.instance = inst.id;
  f.scene = inst.scene;
  f.frame = inst.frame;
  f.q_u.noalias() = pkg.portrait.q_u.row(node).transpose() + w * st.offset_q_u;  // eq. 12
  f.q_a.noalias() = pkg.portrait.q_a.row(node).transpose() + w * st.offset_q_a;  // §5.1, appearance
  f.palette_index = st.palette_index;
  f.irf = st.irf;
  f.irf_t = st.irf_t;
  const auto& kin = pkg.palette.kinematics;
  f.support = support_transform(kin[at(st.kinematics_entry)], st.support_s);
  if (st.jolt_entry >= 0) {
    const auto& k = kin[at(st.jolt_entry)];
    const double p = jolt_pulse(k, static_cast<double>(st.jolt_age) * pkg.attributes.dt);
    f.support =
        compose(support_transform(k, std::clamp(p, double{k.range_min}, double{k.range_max})), f.support);
  }
}

void SynthesisEngine::advance(Instance& inst) const {
  const SceneModel& s = scenes_[at(inst.scene)];
  const auto& pkg = *s.data;
  InstanceState& st = inst.state;
  const double dt = pkg.attributes.dt;
  ++inst.frame;
  ++st.blend_age;
  if (st.jolt_entry >= 0 && static_cast<double>(++st.jolt_age) * dt >
                                kJoltEndTaus * pkg.palette.kinematics[at(st.jolt_entry)].pulse_tau) {
    st.jolt_entry = -1;
    st.jolt_age = 0;
  }
  if (st.mode != Mode::playing) return;
  const auto& k = pkg.palette.kinematics[at(st.palette_index)];
  if (k.pulse_tau == 0 && st.kinematics_entry == st.palette_index) {
    st.support_s += k.rate * dt;
    if (k.range_max > k.range_min)
      st.support_s = std::clamp(st.support_s, double{k.range_min}, double{k.range_max});
  }
  ++st.irf_t;
  const bool ended = static_cast<int>(st.irf_t) >= pkg.portrait.irf_length[at(st.irf)];
  const std::int32_t rule = pkg.palette.on_end[at(st.palette_index)];
  if (range_reached(k, st.support_s) && rule >= 0) {
    end_of_irf(s, st, rule);  // the door reached its stop: the follow-up (stop)
  } else if (ended) {
    // A sampled IRF is only as long as the sampler drew it; while the entry
    // still drives the support within its range (the door is opening and has
    // not reached its stop) the interaction persists on the same entry.
    end_of_irf(s, st, drives_within_range(k, st.support_s) ? core::kEndHold : rule);
  }
}

void SynthesisEngine::apply_due_impulses(Instance& inst, TickResult& out) {
  const auto q = pending_.find(inst.id);
  if (q == pending_.end()) return;
  auto& queue = q->second;
  std::size_t used = 0;
  for (; used < queue.size() && queue[used].frame == inst.frame; ++used) {
    const int d = queue[used].palette_index;
    if (auto why = refusal(scenes_[at(inst.scene)], inst.state, d)) {
      out.refused.push_back({inst.id, d, inst.frame, std::move(*why)});
      continue;
    }
    apply_impulse(inst, d);
    out.applied.push_back({inst.id, d, inst.frame});
  }
  queue.erase(queue.begin(), queue.begin() + static_cast<std::ptrdiff_t>(used));
  if (queue.empty()) pending_.erase(q);
}

TickResult SynthesisEngine::tick() {
  TickResult out;
  tick(out);
  return out;
}

void SynthesisEngine::tick(TickResult& out) {
  out.frames.resize(instances_.size());
  out.applied.clear();
  out.refused.clear();
  auto frame = out.frames.begin();
  for (Instance& inst : instances_ | std::views::values) {
    apply_due_impulses(inst, out);
    synthesize(inst, *frame++);
    advance(inst);
  }
}

}  // namespace phasecast::server
