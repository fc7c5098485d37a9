// Engine throughput: instance-ticks per second on one core at the paper's
// cloth ranks, with impulses arriving all the time (about one per instance
// per second of simulated time), the bytes one frame costs on the wire, and
// the cost of loading a scene with and without the orbit extension's search.

#include "bench_scene.h"
#include "phasecast/core/basis.h"
#include "phasecast/server/synthesis_engine.h"
#include "phasecast/server/wire.h"

#include <benchmark/benchmark.h>

#include <algorithm>

namespace phasecast::bench {
namespace {

using server::SynthesisEngine;

void BM_EngineTick(benchmark::State& state) {
  const auto scene = cloth_ranks_scene();
  SynthesisEngine engine;
  engine.add_scene(scene, "cloth_ranks.h5", 0);
  const auto instances = static_cast<int>(state.range(0));
  for (int i = 0; i < instances; ++i) engine.create_instance("plate");
  const auto& pal = scene->palette;
  std::uint64_t tick = 0, impulses = 0;
  server::TickResult result;  // reused, as the service does, so frames are not allocated every tick
  for (auto _ : state) {
    // Every 60th tick, a deterministic subset of instances gets an allowed impulse.
    if (tick % 60 == 0) {
      for (const auto& [id, inst] : engine.instances()) {
        for (int d = 0; d < pal.size(); ++d) {
          if (pal.allowed(inst.state.palette_index, (d + static_cast<int>(id + tick)) % pal.size())) {
            engine.schedule_impulse(id, (d + static_cast<int>(id + tick)) % pal.size());
            ++impulses;
            break;
          }
        }
      }
    }
    engine.tick(result);
    benchmark::DoNotOptimize(result);
    ++tick;
  }
  state.counters["instance_ticks_per_s"] =
      benchmark::Counter(static_cast<double>(state.iterations()) * instances, benchmark::Counter::kIsRate);
  state.counters["r_u"] = scene->rank_u();
  state.counters["r_a"] = scene->rank_a();
  state.counters["impulses"] = static_cast<double>(impulses);
}
BENCHMARK(BM_EngineTick)->Arg(1)->Arg(100)->Arg(1000)->Unit(benchmark::kMicrosecond);

// Bytes per published frame ([topic][Frame]) against streaming the synthesized
// vertex positions (+ RGB when there is appearance) of the same scene.
void BM_BytesPerFrame(benchmark::State& state) {
  const auto scene = cloth_ranks_scene();
  SynthesisEngine engine;
  engine.add_scene(scene, "cloth_ranks.h5", 0);
  const auto id = engine.create_instance("plate");
  engine.schedule_impulse(id, 2);
  server::TickResult result;
  v1::Frame frame;
  std::string bytes;
  for (auto _ : state) {
    engine.tick(result);
    server::to_frame_message(engine.scenes()[0], result.frames.at(0), frame);
    frame.SerializeToString(&bytes);
    benchmark::DoNotOptimize(bytes.data());
  }
  const double wire = static_cast<double>(bytes.size() + server::instance_topic(id).size());
  state.counters["frame_bytes"] = wire;
  state.counters["reduced_state_bytes"] = static_cast<double>(core::reduced_state_bytes(*scene));
  state.counters["full_vertex_bytes"] = static_cast<double>(core::full_vertex_bytes(*scene));
  state.counters["full_over_frame"] = static_cast<double>(core::full_vertex_bytes(*scene)) / wire;
}
BENCHMARK(BM_BytesPerFrame);

// Loading a scene (add_scene): arg 1 is the package as is, whose open and
// close entries drive the door's limited range and so get an orbit extension
// per IRF (docs/server.md); arg 0 is the same package with every entry's
// support rate at 0, so that none drives the range and no IRF gets an
// extension: the baseline without the extension's search.
void BM_AddScene(benchmark::State& state) {
  auto scene = cloth_ranks_scene();
  if (state.range(0) == 0) {
    auto copy = std::make_shared<core::ScenePackage>(*scene);
    for (auto& k : copy->palette.kinematics) k.rate = 0;
    // The plate has no hold rule; a package with one would keep its extensions.
    for (auto& rule : copy->palette.on_end)
      if (rule == core::kEndHold) rule = core::kEndRest;
    scene = copy;
  }
  for (auto _ : state) {
    SynthesisEngine engine;
    engine.add_scene(scene, "cloth_ranks.h5", 0);
    benchmark::DoNotOptimize(engine.scenes().data());
  }
  SynthesisEngine engine;  // outside the timed loop
  engine.add_scene(scene, "cloth_ranks.h5", 0);
  state.counters["extended_irfs"] = static_cast<double>(
      std::ranges::count_if(engine.scenes()[0].extension, [](const auto& x) { return x.irf >= 0; }));
  state.counters["irfs"] = scene->portrait.irf_count();
  state.counters["nodes"] = scene->portrait.nodes();
}
BENCHMARK(BM_AddScene)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace phasecast::bench
