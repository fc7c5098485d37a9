#include "phasecast/server/wire.h"

#include <fmt/format.h>

namespace phasecast::server {
namespace {

template <class Field>
void put(const VectorXf& v, Field* out) {
  out->Assign(v.data(), v.data() + v.size());
}

template <class Field>
VectorXf get(const Field& f) {
  return Eigen::Map<const VectorXf>(f.data(), f.size());
}

}  // namespace

std::string instance_topic(std::uint32_t instance) {
  return fmt::format("inst/{}/", instance);
}

std::string scene_batch_topic(const std::string& scene, std::uint32_t block) {
  return fmt::format("scene/{}/{}/", scene, block);
}

void begin_frame_batch(const SceneModel& scene, std::uint32_t block, std::uint64_t tick,
                       v1::FrameBatch& out) {
  out.Clear();  // keeps the repeated fields' storage for the next tick
  out.set_scene(scene.name);
  out.set_block(block);
  out.set_tick(tick);
  out.set_rank_u(static_cast<std::uint32_t>(scene.data->rank_u()));
  out.set_rank_a(static_cast<std::uint32_t>(scene.data->rank_a()));
  out.set_dt(scene.data->attributes.dt);
}

void append_to_frame_batch(const SynthesizedFrame& f, v1::FrameBatch& out) {
  out.add_instance(f.instance);
  out.add_frame(f.frame);
  out.mutable_q_u()->Add(f.q_u.data(), f.q_u.data() + f.q_u.size());
  out.mutable_q_a()->Add(f.q_a.data(), f.q_a.data() + f.q_a.size());
  out.mutable_support()->Add(f.support.begin(), f.support.end());
  out.add_palette_index(f.palette_index);
  out.add_irf(f.irf);
  out.add_irf_t(f.irf_t);
}

void to_frame_message(const SceneModel& scene, const SynthesizedFrame& f, v1::Frame& out) {
  out.set_instance(f.instance);
  out.set_seq(f.frame);
  out.set_frame(f.frame);
  out.set_sim_time(static_cast<double>(f.frame) * scene.data->attributes.dt);
  put(f.q_u, out.mutable_q_u());
  put(f.q_a, out.mutable_q_a());
  out.mutable_support()->Assign(f.support.begin(), f.support.end());
  out.set_palette_index(f.palette_index);
  out.set_irf(f.irf);
  out.set_irf_t(f.irf_t);
  out.set_scene(scene.name);
}

void to_snapshot(const InstanceState& s, v1::InstanceSnapshot& out) {
  out.set_mode(static_cast<std::int32_t>(s.mode));
  out.set_palette_index(s.palette_index);
  out.set_irf(s.irf);
  out.set_irf_t(s.irf_t);
  out.set_hold_node(s.hold_node);
  put(s.offset_q_u, out.mutable_offset_q_u());
  put(s.offset_qdot_u, out.mutable_offset_qdot_u());
  put(s.offset_q_a, out.mutable_offset_q_a());
  out.set_blend_age(s.blend_age);
  out.set_support_s(s.support_s);
  out.set_kinematics_entry(s.kinematics_entry);
  out.set_jolt_entry(s.jolt_entry);
  out.set_jolt_age(s.jolt_age);
  out.set_run_group(s.run.group);
  out.set_run_length(s.run.length);
}

InstanceState from_snapshot(const v1::InstanceSnapshot& in, const std::string& where) {
  if (in.mode() != static_cast<std::int32_t>(Mode::rest) &&
      in.mode() != static_cast<std::int32_t>(Mode::playing)) {
    throw EngineError(fmt::format("{}: snapshot mode {} (expected 0 rest or 1 playing)", where, in.mode()));
  }
  InstanceState s;
  s.mode = static_cast<Mode>(in.mode());
  s.palette_index = in.palette_index();
  s.irf = in.irf();
  s.irf_t = in.irf_t();
  s.hold_node = in.hold_node();
  s.offset_q_u = get(in.offset_q_u());
  s.offset_qdot_u = get(in.offset_qdot_u());
  s.offset_q_a = get(in.offset_q_a());
  s.blend_age = in.blend_age();
  s.support_s = in.support_s();
  s.kinematics_entry = in.kinematics_entry();
  s.jolt_entry = in.jolt_entry();
  s.jolt_age = in.jolt_age();
  s.run = {in.run_group(), in.run_length()};
  return s;
}

}  // namespace phasecast::server
