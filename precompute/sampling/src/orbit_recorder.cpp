#include "phasecast/precompute/sampling/orbit_recorder.h"

#include "phasecast/precompute/sampling/scene_palette.h"

#include <fmt/format.h>

#include <charconv>
#include <cmath>
#include <filesystem>
#include <sstream>

namespace phasecast::precompute {
namespace {

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\n");
  if (b == std::string::npos) return "";
  return s.substr(b, s.find_last_not_of(" \t\n") - b + 1);
}

}  // namespace

int schedule_frames(double seconds, double frame_dt) {
  return static_cast<int>(std::lround(seconds / frame_dt));
}

std::vector<ScheduleItem> parse_schedule(const std::string& text, const Scene& scene) {
  std::vector<ScheduleItem> items;
  std::stringstream all(text);
  for (std::string part; std::getline(all, part, ';');) {
    part = trim(part);
    if (part.empty()) continue;
    std::istringstream words(part);
    std::string name, duration, extra;
    words >> name >> duration >> extra;
    double seconds = 0;
    const auto [end, ec] = std::from_chars(duration.data(), duration.data() + duration.size(), seconds);
    if (duration.empty() || ec != std::errc() || end != duration.data() + duration.size() || !extra.empty() ||
        !(seconds > 0) || !std::isfinite(seconds)) {
      throw SceneError(fmt::format("schedule item '{}': expected '<palette entry> <seconds > 0>'", part));
    }
    if (schedule_frames(seconds, scene.simulation.frame_dt) < 1) {
      throw SceneError(
          fmt::format("schedule item '{}': shorter than one frame ({} s)", part, scene.simulation.frame_dt));
    }
    items.push_back({scene.palette_index(name), seconds});
  }
  if (items.empty())
    throw SceneError(fmt::format("schedule '{}': expected at least one '<entry> <seconds>' item", text));
  return items;
}

OrbitStore empty_orbit_store(const Scene& scene) {
  OrbitStore s;
  s.scene = scene.name;
  s.source = "phasecast-simulator";
  if (!scene.source.empty())
    s.scene_file = std::filesystem::absolute(scene.source).lexically_normal().string();
  s.dt = scene.simulation.frame_dt;
  const auto& m = scene.model;
  s.rest_positions = Eigen::Map<const RowMatrix<double>>(m.rest.data(), m.vertices(), 3).cast<float>();
  s.triangles = m.surface.cast<std::uint32_t>();
  s.segments.resize(static_cast<Eigen::Index>(m.rod_stretch.size()), 2);
  for (size_t e = 0; e < m.rod_stretch.size(); ++e) {
    s.segments.row(static_cast<Eigen::Index>(e)) << static_cast<std::uint32_t>(m.rod_stretch[e].a),
        static_cast<std::uint32_t>(m.rod_stretch[e].b);
  }
  s.pinned = m.pinned;
  auto palette = palette_arrays(scene);
  s.palette_names = std::move(palette.names);
  s.alpha_impulse = std::move(palette.alpha_impulse);
  s.alpha_forcing = std::move(palette.alpha_forcing);
  s.kinematics = std::move(palette.kinematics);
  s.support.resize(0, core::kSupportFloats);
  return s;
}

void record_irf_frames(Simulator& simulator, const Scene& scene, int entry, int frames, bool continues,
                       IrfFrames& out, const std::function<void()>& on_frame) {
  const auto& e = scene.palette.at(static_cast<size_t>(entry));
  const Eigen::Index n = 3 * static_cast<Eigen::Index>(simulator.vertices());
  out.entry = entry;
  out.continues = continues;
  out.positions.resize(frames, n);
  out.velocities.resize(frames, n);
  out.support.resize(frames, core::kSupportFloats);
  simulator.impulse(e.alpha_impulse);
  for (int f = 0; f < frames; ++f) {
    const auto& st = simulator.state();
    out.positions.row(f) = st.x.cast<float>().transpose();
    out.velocities.row(f) = st.v.cast<float>().transpose();
    const Eigen::Matrix<double, 3, 4, Eigen::RowMajor> T = simulator.support_transform();
    out.support.row(f) = Eigen::Map<const Eigen::Matrix<double, 1, 12>>(T.data()).cast<float>();
    simulator.step(e.alpha_forcing);
    if (on_frame) on_frame();
  }
}

void record_irf(Simulator& simulator, const Scene& scene, int entry, int frames, OrbitStore& store,
                const std::function<void()>& on_frame, bool continues) {
  IrfFrames irf;
  record_irf_frames(simulator, scene, entry, frames, continues, irf, on_frame);
  append_irf(store, irf);
}

void settle(Simulator& simulator, double seconds) {
  const Eigen::VectorXd none = Eigen::VectorXd::Zero(simulator.alpha_size());
  const int steps = schedule_frames(seconds, simulator.frame_dt());
  for (int i = 0; i < steps; ++i) {
    simulator.step(none);
    SimState s = simulator.state();
    s.v.setZero();
    s.time = 0;
    simulator.reset(s);
  }
}

SimState settled_rest_state(const Scene& scene, Simulator& simulator) {
  simulator.reset(simulator.rest_state());
  settle(simulator, scene.simulation.settle);
  return simulator.state();
}

OrbitStore simulate_schedule(const Scene& scene, const std::vector<ScheduleItem>& schedule,
                             const ProgressCallback& progress) {
  auto simulator = make_simulator(scene);
  settled_rest_state(scene, *simulator);
  OrbitStore store = empty_orbit_store(scene);
  int total = 0, done = 0;
  for (const auto& item : schedule) total += schedule_frames(item.duration, scene.simulation.frame_dt);
  for (const auto& item : schedule) {
    record_irf(*simulator, scene, item.entry, schedule_frames(item.duration, scene.simulation.frame_dt),
               store, [&] {
                 if (progress) progress(++done, total);
               });
  }
  return store;
}

}  // namespace phasecast::precompute
