#include "phasecast/precompute/simulation/blender_simulator.h"

#include "blender_process.h"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <functional>
#include <string_view>

namespace phasecast::precompute {
namespace {

using detail::BlenderProcess;
using Transform = Eigen::Matrix<double, 3, 4>;

std::string driver_config(const BlenderSettings& s, double frame_dt) {
  // Blender's frame rate is fps / fps_base frames per second.
  const int fps = std::max(1, static_cast<int>(std::lround(1 / frame_dt)));
  return nlohmann::json{{"fps", fps},           {"fps_base", fps * frame_dt}, {"frame_dt", frame_dt},
                        {"support", s.support}, {"deformable", s.deformable}, {"drawn", s.drawn}}
      .dump();
}

nlohmann::json parse_answer(const std::string& line, const BlenderSettings& s) {
  nlohmann::json answer;
  try {
    answer = nlohmann::json::parse(line);
  } catch (const nlohmann::json::exception&) {
    throw SimulationError(fmt::format("Blender on {}: the driver answered '{}' (expected JSON)",
                                      s.blend.string(), line.substr(0, 80)));
  }
  if (answer.contains("error"))
    throw SimulationError(fmt::format("{}: {}", s.blend.string(), answer["error"].get<std::string>()));
  return answer;
}

nlohmann::json read_json(BlenderProcess& process, const BlenderSettings& s) {
  return parse_answer(process.read_line(), s);
}

// Rows of Phasecast points from a flat list of Blender xyz.
Eigen::MatrixX3d phasecast_rows(const nlohmann::json& flat) {
  const auto xyz = flat.get<std::vector<double>>();
  Eigen::MatrixX3d rows(static_cast<Eigen::Index>(xyz.size() / 3), 3);
  for (Eigen::Index v = 0; v < rows.rows(); ++v)
    rows.row(v) = blender_to_phasecast() * Eigen::Map<const Eigen::Vector3d>(xyz.data() + 3 * v);
  return rows;
}

Eigen::Vector3d colour_of(const nlohmann::json& rgb) {
  return Eigen::Vector3d(rgb.at(0).get<double>(), rgb.at(1).get<double>(), rgb.at(2).get<double>());
}

// A drawn object: its evaluated mesh, one point per distinct corner normal.
PropMesh prop_mesh(const nlohmann::json& drawn) {
  PropMesh m{drawn.at("name"), phasecast_rows(drawn.at("vertices")), phasecast_rows(drawn.at("normals")),
             Eigen::MatrixX3i(static_cast<Eigen::Index>(drawn.at("triangles").size()), 3),
             colour_of(drawn.at("colour"))};
  for (Eigen::Index t = 0; t < m.triangles.rows(); ++t)
    for (int k = 0; k < 3; ++k) m.triangles(t, k) = drawn.at("triangles").at(t).at(k).get<int>();
  return m;
}

std::size_t position_hash(const Eigen::VectorXd& x) {
  return std::hash<std::string_view>{}(std::string_view(reinterpret_cast<const char*>(x.data()),
                                                        sizeof(double) * static_cast<size_t>(x.size())));
}

class BlenderSimulator final : public Simulator {
 public:
  BlenderSimulator(BlenderSettings settings, double frame_dt, const SupportSettings& support,
                   const Eigen::VectorXd& rest)
      : settings_(std::move(settings)), frame_dt_(frame_dt), motion_(support) {
    rest_.x = rest;
    rest_.v = Eigen::VectorXd::Zero(rest.size());
    restart();
  }

  int vertices() const override { return static_cast<int>(rest_.x.size() / 3); }
  double frame_dt() const override { return frame_dt_; }
  int alpha_size() const override { return 3; }
  SimState rest_state() const override { return rest_; }
  const SimState& state() const override { return state_; }
  bool restores_any_state() const override { return false; }
  Transform support_transform() const override { return motion_.transform(state_.support); }

  // Blender keeps its own velocities: a reset to the current positions (the
  // quasi-static settle's) only adopts the support state and the clock. Any
  // other state this process passed through is reached again by replaying
  // the support's motion from a new process (Blender is deterministic).
  void reset(const SimState& s) override {
    const std::size_t h = position_hash(s.x);
    if (h != visited_.back()) {
      // The latest visit: a cloth at rest may pass through the same positions more than once.
      const auto found = std::find(visited_.rbegin(), visited_.rend(), h);
      const auto k = visited_.rend() - found - 1;
      if (found == visited_.rend()) {
        throw SimulationError(fmt::format(
            "{}: Blender returns only to states it reached itself since it started (not a checkpoint of "
            "another process)",
            settings_.blend.string()));
      }
      const std::vector<Transform> replay(motions_.begin(), motions_.begin() + k);
      restart();
      for (const auto& T : replay) advance_blender(T);
      if (position_hash(state_.x) != h) {
        throw SimulationError(fmt::format(
            "{}: Blender replayed {} frames to other positions than the first time (not deterministic?)",
            settings_.blend.string(), replay.size()));
      }
    }
    state_.support = s.support;
    state_.time = s.time;
  }

  void impulse(const Eigen::VectorXd& alpha_impulse) override {
    motion_.impulse(state_.support, checked(alpha_impulse, "impulse"));
  }

  void step(const Eigen::VectorXd& alpha_forcing) override {
    motion_.hold(state_.support, checked(alpha_forcing, "step"));
    motion_.advance(state_.support, frame_dt_);
    advance_blender(motion_.transform(state_.support));
    state_.time += frame_dt_;
  }

 private:
  Eigen::Vector3d checked(const Eigen::VectorXd& alpha, const char* what) const {
    if (alpha.size() != 3 || !alpha.allFinite())
      throw SimulationError(fmt::format("{}: alpha must be 3 finite numbers (got {})", what, alpha.size()));
    return alpha;
  }

  void restart() {
    process_.reset();
    process_ = std::make_unique<BlenderProcess>(settings_.blend, "simulate",
                                                driver_config(settings_, frame_dt_), settings_.timeout);
    const auto ready = read_json(*process_, settings_);
    if (ready.at("vertices").get<int>() != vertices()) {
      throw SimulationError(fmt::format("{}: the deformable objects have {} vertices, the scene {}",
                                        settings_.blend.string(), ready.at("vertices").get<int>(),
                                        vertices()));
    }
    state_ = rest_;
    motions_.clear();
    visited_.assign(1, position_hash(state_.x));
  }

  // One Blender frame with the support moved by T (Phasecast's world), then
  // the deformable points back in the support's frame.
  void advance_blender(const Transform& T) {
    const Eigen::Matrix3d C = blender_to_phasecast();
    const Eigen::Matrix3d R = C.transpose() * T.leftCols<3>() * C;
    const Eigen::Vector3d t = C.transpose() * T.col(3);
    std::string request = "step";
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) request += fmt::format(" {:.17g}", R(r, c));
      request += fmt::format(" {:.17g}", t(r));
    }
    process_->write(request + "\n");
    if (const std::string line = process_->read_line(); line != "ok") {
      parse_answer(line, settings_);  // the driver's error
      throw SimulationError(fmt::format("Blender on {}: the driver answered '{}' to a step",
                                        settings_.blend.string(), line.substr(0, 80)));
    }
    Eigen::VectorXd world(rest_.x.size());
    process_->read_exact(world.data(), sizeof(double) * static_cast<size_t>(world.size()));
    const Eigen::Matrix3d Rt = T.leftCols<3>().transpose();
    const Eigen::VectorXd before = state_.x;
    for (Eigen::Index v = 0; v < world.size() / 3; ++v)
      state_.x.segment<3>(3 * v) = Rt * (C * world.segment<3>(3 * v) - T.col(3));
    if (!state_.x.allFinite())
      throw SimulationError(fmt::format("{}: Blender's positions are not finite", settings_.blend.string()));
    state_.v = (state_.x - before) / frame_dt_;
    motions_.push_back(T);
    visited_.push_back(position_hash(state_.x));
  }

  BlenderSettings settings_;
  double frame_dt_;
  SupportMotion motion_;
  SimState rest_, state_;
  std::unique_ptr<BlenderProcess> process_;
  std::vector<Transform> motions_;    // the support's motion of each frame since the process started
  std::vector<std::size_t> visited_;  // positions after each of those frames (0: the first frame)
};

}  // namespace

Eigen::Matrix3d blender_to_phasecast() {
  Eigen::Matrix3d C;
  C << 1, 0, 0, 0, 0, 1, 0, -1, 0;
  return C;
}

BlenderDescription describe_blender_scene(const BlenderSettings& settings, double frame_dt) {
  BlenderProcess process(settings.blend, "describe", driver_config(settings, frame_dt), settings.timeout);
  const nlohmann::json d = read_json(process, settings);
  BlenderDescription out;
  const auto& xyz = d.at("vertices");
  out.rest.resize(static_cast<Eigen::Index>(xyz.size()));
  const auto world = xyz.get<std::vector<double>>();
  for (size_t v = 0; v + 2 < world.size(); v += 3)
    out.rest.segment<3>(static_cast<Eigen::Index>(v)) =
        blender_to_phasecast() * Eigen::Vector3d(world[v], world[v + 1], world[v + 2]);
  const auto& tris = d.at("triangles");
  out.triangles.resize(static_cast<Eigen::Index>(tris.size()), 3);
  for (size_t t = 0; t < tris.size(); ++t)
    for (int k = 0; k < 3; ++k) out.triangles(static_cast<Eigen::Index>(t), k) = tris[t].at(k).get<int>();
  out.pinned = d.at("pinned").get<std::vector<std::uint8_t>>();
  for (const auto& b : d.at("bodies")) {
    out.bodies.push_back({b.at("name"), b.at("first"), b.at("count"), b.at("first_triangle"),
                          b.at("triangles"), colour_of(b.at("colour"))});
  }
  for (const auto& b : d.at("drawn")) out.drawn.push_back(prop_mesh(b));
  out.self_collision = d.at("self_collision");
  out.self_distance = d.at("self_distance");
  return out;
}

std::unique_ptr<Simulator> make_blender_simulator(const BlenderSettings& settings, double frame_dt,
                                                  const SupportSettings& support,
                                                  const Eigen::VectorXd& rest) {
  return std::make_unique<BlenderSimulator>(settings, frame_dt, support, rest);
}

}  // namespace phasecast::precompute
