#include "phasecast/precompute/validation/playback.h"

#include "phasecast/precompute/sampling/irf_sampler.h"
#include "phasecast/precompute/simulation/render_surface.h"
#include "phasecast/precompute/simulation/self_collision.h"
#include "phasecast/server/synthesis_engine.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace phasecast::precompute {
namespace {

// Per-frame motion below 0.01 mm RMS counts as still: ratios and NRMSE use it
// as a floor so a still schedule or segment does not divide by ~0.
constexpr double kStill = 1e-5;

// RMS per vertex of a 3V vector.
double rms(const Eigen::VectorXd& d) {
  return d.size() ? std::sqrt(d.squaredNorm() / (static_cast<double>(d.size()) / 3)) : 0;
}

// The served shapes x-bar + U_u q_u of the render surface's points, one row
// per frame, and the IRF each frame played, from the real synthesis engine.
struct Served {
  Eigen::MatrixXd x;                 // N x 3P
  std::vector<std::int32_t> irf;     // N: IRF played (-1 at rest)
  std::vector<std::uint32_t> irf_t;  // N: node inside it
  std::vector<std::string> refused;  // per schedule item
};

Served serve(std::shared_ptr<const core::ScenePackage> package, const std::vector<int>& starts,
             const std::vector<ScheduleItem>& schedule, int frames, Eigen::Index coordinates) {
  server::SynthesisEngine engine;
  engine.add_scene(package, "validate", 0);
  const std::uint32_t id = engine.create_instance(package->attributes.scene);
  const VectorXf mean = package->reduction.mean_shape.head(coordinates);
  const MatrixXfR U = package->reduction.U_u.topRows(coordinates);
  Served s;
  s.x.resize(frames, coordinates);
  s.refused.resize(schedule.size());
  size_t next = 0;
  for (int f = 0; f < frames; ++f) {
    for (; next < schedule.size() && starts[next] == f; ++next) {
      try {
        engine.schedule_impulse(id, schedule[next].entry, static_cast<std::uint64_t>(f));
      } catch (const server::EngineError& e) {
        s.refused[next] = e.what();
      }
    }
    const server::TickResult made = engine.tick();
    for (const auto& r : made.refused) {
      for (size_t k = 0; k < schedule.size(); ++k)
        if (starts[k] == static_cast<int>(r.frame)) s.refused[k] = r.error;
    }
    const auto& frame = made.frames.front();
    s.x.row(f) = (mean + U * frame.q_u).cast<double>().transpose();
    s.irf.push_back(frame.irf);
    s.irf_t.push_back(frame.irf_t);
  }
  return s;
}

Eigen::VectorXd motion(const Eigen::MatrixXd& x, int f) {
  return (x.row(f) - x.row(f - 1)).transpose();
}

SegmentFigures segment(const Eigen::MatrixXd& sim, const Eigen::MatrixXd& served, int first, int count,
                       double scale) {
  SegmentFigures g;
  g.first_frame = first;
  g.frames = count;
  double error = 0, moved_sim = 0, moved_served = 0;
  for (int f = first; f < first + count; ++f) {
    error += (served.row(f) - sim.row(f)).squaredNorm();
    if (f > first) {
      moved_sim += motion(sim, f).squaredNorm();
      moved_served += motion(served, f).squaredNorm();
    }
  }
  const double V = static_cast<double>(sim.cols()) / 3;
  const double floor2 = kStill * kStill * V * std::max(1, count - 1);
  g.nrmse = std::sqrt(error / count / V) / std::max(scale, kStill);
  g.motion_ratio = (moved_served + floor2) / (moved_sim + floor2);
  g.simulated_motion = count > 1 ? std::sqrt(moved_sim / (count - 1) / V) : 0;
  return g;
}

// Switches: frames whose IRF differs from the previous frame's, or restarts.
// The switch frame shows the state the impulse arrived in (eq. 12's offset at
// weight 1); the new IRF and its blend show from the next frame, so the jump
// is measured from f to f + 1.
std::vector<SwitchFigures> switches(const Eigen::MatrixXd& sim, const Served& served) {
  std::vector<SwitchFigures> out;
  const int N = static_cast<int>(sim.rows());
  for (int f = 1; f + 1 < N; ++f) {
    const auto k = static_cast<size_t>(f);
    const bool restarted = served.irf[k] >= 0 && served.irf_t[k] == 0;  // an impulse chose the same IRF again
    if (served.irf[k] == served.irf[k - 1] && !restarted) continue;
    SwitchFigures s;
    s.frame = f;
    s.jump = rms(motion(served.x, f + 1));
    double local = 0;
    int n = 0;
    for (int g = std::max(1, f - 1); g <= std::min(N - 1, f + 3); ++g, ++n) local += rms(motion(sim, g));
    s.local_motion = std::max(kStill, n ? local / n : 0);
    out.push_back(s);
  }
  return out;
}

// Speeds at the last node of each IRF after which the served scene came to
// rest (holds that node): an IRF that ends mid-motion freezes the scene there.
// IRFs continued by another (the door still opening) are not ends.
std::vector<double> irf_end_speeds(const Served& served, double dt) {
  std::vector<double> out;
  for (size_t f = 1; f + 1 < served.irf.size(); ++f) {
    if (served.irf[f] >= 0 && served.irf[f + 1] < 0)
      out.push_back(rms(motion(served.x, static_cast<int>(f))) / dt);
  }
  return out;
}

// The simulated frames (N x 3V) where the render surface shows them (N x 3P):
// the frames themselves when no body has a render mesh.
Eigen::MatrixXd embedded_frames(const RenderSurface& surface, const MatrixXfR& frames) {
  return embed_positions(surface.embedding(), frames.transpose()).transpose().cast<double>();
}

// The package's first P scene points must be the scene's render surface at rest.
void check_render_surface(const Scene& scene, const RenderSurface& surface, const core::SceneMesh& mesh,
                          const std::string& who) {
  const MatrixXfR rest = embed_positions(surface.embedding(), scene.model.rest.cast<float>());
  const Eigen::Index P = surface.points();
  const bool same =
      mesh.points() >= P && (Eigen::Map<const MatrixXfR>(rest.data(), P, 3) - mesh.rest_positions.topRows(P))
                                    .cwiseAbs()
                                    .maxCoeff() <= 1e-5f;
  if (!same) {
    throw std::invalid_argument(fmt::format(
        "validate: {}the package's scene points are not the {} render-surface points of scene file "
        "'{}' (was the "
        "package built from another version of it?)",
        who, P, scene.name));
  }
}

// `path`, when given, names the package in the messages.
void check_package_of(const Scene& scene, const RenderSurface& surface, const core::ScenePackage& package,
                      const std::string& path = {}) {
  const std::string who = path.empty() ? "" : path + ": ";
  const double dt = scene.simulation.frame_dt;
  if (std::abs(package.attributes.dt - dt) > 1e-9 || package.attributes.scene != scene.name) {
    throw std::invalid_argument(
        fmt::format("validate: {}package of scene '{}' at dt {} s does not match scene file '{}' at dt {} s",
                    who, package.attributes.scene, package.attributes.dt, scene.name, dt));
  }
  check_render_surface(scene, surface, package.mesh, who);
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

}  // namespace

double typical_motion(const ScheduleFigures& g) {
  double sum = 0;
  int n = 0;
  for (const auto& s : g.segments) sum += s.simulated_motion * (s.frames - 1), n += s.frames - 1;
  return n ? sum / n : 0;
}

bool is_moving(const SegmentFigures& s, double typical) {
  return s.frames > 1 && s.simulated_motion > kStill && s.simulated_motion >= 0.1 * typical;
}

void ValidationSummary::add(const ScheduleFigures& g) {
  nrmse.push_back(g.nrmse);
  const double typical = typical_motion(g);
  for (const auto& seg : g.segments) {
    if (!is_moving(seg, typical)) continue;
    ++moving;
    moving_within += seg.motion_ratio >= kMotionLow && seg.motion_ratio <= kMotionHigh;
  }
  for (const auto& w : g.switches) ++switches, switches_within += w.ratio() <= kJumpRatio;
  intersecting_frames += g.frames_with_intersections;
}

double ValidationSummary::nrmse_percentile(double p) const {
  if (nrmse.empty()) return 0;
  std::vector<double> v = nrmse;
  std::sort(v.begin(), v.end());
  const double at = p * static_cast<double>(v.size() - 1);
  const auto lo = static_cast<size_t>(std::floor(at));
  const size_t hi = std::min(lo + 1, v.size() - 1);
  return v[lo] + (at - static_cast<double>(lo)) * (v[hi] - v[lo]);
}

nlohmann::json ValidationSummary::to_json() const {
  return {{"median_nrmse", median_nrmse()},
          {"p90_nrmse", p90_nrmse()},
          {"moving_segments", moving},
          {"moving_segments_within", moving_within},
          {"switches", switches},
          {"switches_within", switches_within},
          {"frames_with_intersections", intersecting_frames}};
}

std::string schedule_text(const Scene& scene, const std::vector<ScheduleItem>& schedule) {
  std::string s;
  for (const auto& item : schedule)
    s += fmt::format("{}{} {:.2f}", s.empty() ? "" : "; ",
                     scene.palette[static_cast<size_t>(item.entry)].name, item.duration);
  return s;
}

void check_package_of(const Scene& scene, const core::ScenePackage& package, const std::string& path) {
  check_package_of(scene, render_surface(scene), package, path);
}

SimulatedSchedule simulate_truth(const Scene& scene, const std::vector<ScheduleItem>& schedule,
                                 const ProgressCallback& progress) {
  const OrbitStore truth = simulate_schedule(scene, schedule, progress);
  return {schedule, embedded_frames(render_surface(scene), truth.positions)};
}

ScheduleFigures validate_schedule(const Scene& scene, std::shared_ptr<const core::ScenePackage> package,
                                  const std::vector<ScheduleItem>& schedule, const ValidationOptions& o) {
  check_package_of(scene, *package);
  return compare_playback(scene, package, simulate_truth(scene, schedule, o.progress), o);
}

ScheduleFigures compare_playback(const Scene& scene, std::shared_ptr<const core::ScenePackage> package,
                                 const SimulatedSchedule& truth, const ValidationOptions& o) {
  const RenderSurface surface = render_surface(scene);
  check_package_of(scene, surface, *package);
  const double dt = scene.simulation.frame_dt;
  const std::vector<ScheduleItem>& schedule = truth.items;
  const Eigen::MatrixXd& sim = truth.frames;
  const int N = static_cast<int>(sim.rows());
  std::vector<int> starts;
  for (int f = 0; const auto& item : schedule) starts.push_back(f), f += schedule_frames(item.duration, dt);
  const Served served = serve(package, starts, schedule, N, sim.cols());

  ScheduleFigures out;
  out.schedule = schedule_text(scene, schedule);
  out.frames = N;
  const Eigen::RowVectorXd mean = sim.colwise().mean();
  const double scale =
      std::sqrt((sim.rowwise() - mean).squaredNorm() / N / (static_cast<double>(sim.cols()) / 3));
  const SegmentFigures all = segment(sim, served.x, 0, N, scale);
  out.nrmse = all.nrmse;
  out.motion_ratio = all.motion_ratio;
  for (size_t k = 0; k < schedule.size(); ++k) {
    SegmentFigures g = segment(sim, served.x, starts[k], schedule_frames(schedule[k].duration, dt), scale);
    g.entry = scene.palette[static_cast<size_t>(schedule[k].entry)].name;
    g.refused = served.refused[k];
    g.unsampled = !g.refused.empty() && std::ranges::find(package->portrait.irf_palette, schedule[k].entry) ==
                                            package->portrait.irf_palette.end();
    out.segments.push_back(std::move(g));
  }
  for (int f = 0; f < N; ++f) {
    out.served_trace.push_back(rms((served.x.row(f) - sim.row(0)).transpose()));
    out.simulated_trace.push_back(rms((sim.row(f) - sim.row(0)).transpose()));
  }
  out.switches = switches(sim, served);
  out.irf_end_speeds = irf_end_speeds(served, dt);
  std::vector<double> speeds;
  for (int f = 1; f < N; ++f) speeds.push_back(rms(motion(sim, f)) / dt);
  out.median_simulated_speed = median(speeds);
  if (o.intersections) {
    const Eigen::MatrixXi contact = contact_triangles(surface);
    for (int f = 0; f < N; ++f) {
      const int pairs = count_intersecting_pairs(served.x.row(f).transpose(), contact);
      out.frames_with_intersections += pairs > 0;
      out.max_intersecting_pairs = std::max(out.max_intersecting_pairs, pairs);
    }
  }
  return out;
}

std::vector<ScheduleItem> random_schedule(const PaletteRules& rules, double frame_dt, std::uint64_t seed,
                                          int index, int items) {
  // Another stream than the sampler's chains (seed offset), the same rules.
  const std::uint64_t stream = seed ^ 0x76616c6964617465ULL;  // "validate"
  std::vector<ScheduleItem> out;
  std::vector<int> history;
  double at = 0;
  for (int i = 0; i < items; ++i) {
    const IrfDraw d = draw_irf(rules, stream, index, i, history, at);
    if (d.from_rest) break;  // a user cannot put the scene back to rest
    history.push_back(d.entry);
    at = rules.advance(d.entry, at, d.frames);
    out.push_back({d.entry, d.frames * frame_dt});
  }
  return out;
}

nlohmann::json to_json(const ScheduleFigures& g) {
  nlohmann::json j = {{"schedule", g.schedule},
                      {"frames", g.frames},
                      {"nrmse", g.nrmse},
                      {"motion_ratio", g.motion_ratio},
                      {"irf_end_speeds", g.irf_end_speeds},
                      {"median_simulated_speed", g.median_simulated_speed},
                      {"frames_with_intersections", g.frames_with_intersections},
                      {"max_intersecting_pairs", g.max_intersecting_pairs},
                      {"served_trace", g.served_trace},
                      {"simulated_trace", g.simulated_trace}};
  for (const auto& s : g.segments) {
    j["segments"].push_back({{"entry", s.entry},
                             {"first_frame", s.first_frame},
                             {"frames", s.frames},
                             {"refused", s.refused},
                             {"nrmse", s.nrmse},
                             {"motion_ratio", s.motion_ratio},
                             {"simulated_motion", s.simulated_motion}});
  }
  for (const auto& s : g.switches) {
    j["switches"].push_back(
        {{"frame", s.frame}, {"jump", s.jump}, {"local_motion", s.local_motion}, {"ratio", s.ratio()}});
  }
  return j;
}

}  // namespace phasecast::precompute
