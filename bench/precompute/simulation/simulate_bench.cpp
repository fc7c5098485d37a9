// bench_precompute: what the paper is about, in one ratio. One frame of the
// implicit simulator (Newton + sparse Cholesky, contact) against a rank-r
// reconstruction u = U_u q_u of the same mesh, which is what a thin client
// evaluates per frame once the IRFs are precomputed (the server's own
// synthesis step is O(r) and lives in server/).

#include "bench_scenes.h"
#include "phasecast/precompute/sampling/orbit_recorder.h"
#include "phasecast/precompute/simulation/scene.h"

#include <benchmark/benchmark.h>

#include <random>

namespace {

using phasecast::precompute::load_scene_file;

const std::filesystem::path kScenes = phasecast::bench::scenes_dir();

// Frames of `scene` under palette entry `entry` (impulse once, then forcing),
// from the settled rest every sampled chain starts from (a fold that has not
// settled yet costs more contact work than any frame the sampler computes).
void simulate_frames(benchmark::State& state, const char* scene_name, const char* entry) {
  const auto scene = load_scene_file(kScenes / (std::string(scene_name) + ".toml"));
  const auto& e = scene.palette.at(static_cast<size_t>(scene.palette_index(entry)));
  auto sim = make_simulator(scene);
  phasecast::precompute::settled_rest_state(scene, *sim);
  sim->impulse(e.alpha_impulse);
  for (auto _ : state) {
    sim->step(e.alpha_forcing);
    benchmark::DoNotOptimize(sim->state().x.data());
  }
  state.counters["vertices"] = scene.model.vertices();
  state.counters["frames_per_s"] =
      benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
  state.counters["sim_s_per_wall_s"] = benchmark::Counter(
      static_cast<double>(state.iterations()) * scene.simulation.frame_dt, benchmark::Counter::kIsRate);
}

void BM_ClothDoorFrame(benchmark::State& s) {
  simulate_frames(s, "cloth_door", "open");
}
void BM_PlantPotFrame(benchmark::State& s) {
  simulate_frames(s, "plant_pot", "right");
}
void BM_ToyDashboardFrame(benchmark::State& s) {
  simulate_frames(s, "toy_dashboard", "forward");
}
// Table 1's cloth at the paper's size: a folded towel in persistent self-contact.
void BM_PaperClothDoorFrame(benchmark::State& s) {
  simulate_frames(s, "paper/cloth_door", "open");
}
void BM_PaperPlantPotFrame(benchmark::State& s) {
  simulate_frames(s, "paper/plant_pot", "right");
}
void BM_PaperToyDashboardFrame(benchmark::State& s) {
  simulate_frames(s, "paper/toy_dashboard", "forward");
}
BENCHMARK(BM_ClothDoorFrame)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(40);
BENCHMARK(BM_PaperClothDoorFrame)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(50);
BENCHMARK(BM_PlantPotFrame)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(100);
BENCHMARK(BM_ToyDashboardFrame)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(20);
BENCHMARK(BM_PaperPlantPotFrame)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(30);
BENCHMARK(BM_PaperToyDashboardFrame)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(30);

// u = U_u q_u for the cloth_door mesh at rank r (float, as on the client).
void BM_ClothDoorReducedReconstruction(benchmark::State& state) {
  const auto scene = load_scene_file(kScenes / "cloth_door.toml");
  const auto rows = 3 * scene.model.vertices();
  const auto r = static_cast<Eigen::Index>(state.range(0));
  std::mt19937 rng(1);
  std::normal_distribution<float> n(0, 1);
  Eigen::MatrixXf U(rows, r);
  Eigen::VectorXf q(r);
  for (Eigen::Index i = 0; i < U.size(); ++i) U.data()[i] = n(rng);
  for (Eigen::Index i = 0; i < r; ++i) q[i] = n(rng);
  Eigen::VectorXf u(rows);
  for (auto _ : state) {
    u.noalias() = U * q;
    benchmark::DoNotOptimize(u.data());
  }
}
BENCHMARK(BM_ClothDoorReducedReconstruction)->Arg(20)->Arg(64)->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
