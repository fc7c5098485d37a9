// Ray casting and transfer precompute speed on a cloth-like scene: a wavy
// double-sided sheet (the cloth, both sides scene points) hanging in front of
// a board (the door). Figures go to docs/performance-transfer.md.
//
// bench_transfer [--grid=N] (sheet points per side, default 64) plus the
// usual --benchmark_* flags. Ray figures are one thread (rays/s per core);
// transfer figures are for one thread and for all cores.

#include "phasecast/core/mesh_geometry.h"
#include "phasecast/precompute/appearance/kmeans.h"
#include "phasecast/precompute/appearance/nrbf.h"
#include "phasecast/precompute/appearance/transfer.h"
#include "phasecast/precompute/appearance/transfer_appearance.h"
#include "phasecast/precompute/appearance/transfer_file.h"
#include "phasecast/precompute/appearance/transfer_rays.h"
#include "phasecast/precompute/appearance/transfer_reduction.h"

#include <benchmark/benchmark.h>
#include <tbb/global_control.h>

#include <cmath>
#include <cstring>
#include <random>
#include <string>
#include <thread>

namespace phasecast::precompute {
namespace {

int g_grid = 64;

TransferMesh sheet_and_board(int n) {
  TransferMesh sheet;
  sheet.positions.resize(n * n, 3);
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const float u = static_cast<float>(i) / static_cast<float>(n - 1);
      const float v = static_cast<float>(j) / static_cast<float>(n - 1);
      // Folds along u that deepen towards the bottom, like hanging cloth.
      sheet.positions.row(j * n + i) << u, v, 0.1f * (1 - v) * std::sin(12 * u) + 0.15f;
    }
  }
  sheet.triangles.resize(2 * (n - 1) * (n - 1), 3);
  int t = 0;
  for (int j = 0; j + 1 < n; ++j) {
    for (int i = 0; i + 1 < n; ++i) {
      const auto a = static_cast<std::uint32_t>(j * n + i), b = a + 1, c = a + static_cast<std::uint32_t>(n),
                 d = c + 1;
      sheet.triangles.row(t++) << a, b, d;
      sheet.triangles.row(t++) << a, d, c;
    }
  }
  sheet.normals = core::vertex_normals(sheet.positions, sheet.triangles);
  TransferMesh scene = make_double_sided(sheet);
  // The board: a 2-triangle quad behind the sheet facing it.
  const auto S = static_cast<std::uint32_t>(scene.positions.rows());
  scene.positions.conservativeResize(S + 4, 3);
  scene.normals.conservativeResize(S + 4, 3);
  scene.positions.bottomRows(4) << -0.2f, -0.2f, 0, 1.2f, -0.2f, 0, 1.2f, 1.2f, 0, -0.2f, 1.2f, 0;
  scene.normals.bottomRows(4).setZero();
  scene.normals.bottomRows(4).col(2).setOnes();
  const auto F = scene.triangles.rows();
  scene.triangles.conservativeResize(F + 2, 3);
  scene.triangles.row(F) << S, S + 1, S + 2;
  scene.triangles.row(F + 1) << S, S + 2, S + 3;
  return scene;
}

const TransferMesh& scene() {
  static const TransferMesh s = sheet_and_board(g_grid);
  return s;
}

// Rays from the scene points along their hemispheres, as the transfer casts them.
struct RaySet {
  std::vector<std::array<float, 3>> origins, dirs;
};

RaySet hemisphere_rays(const TransferMesh& m, int count) {
  std::mt19937_64 rng(1);
  const MatrixXfR d = sphere_directions(1024);
  RaySet r;
  while (static_cast<int>(r.origins.size()) < count) {
    const auto p = static_cast<Eigen::Index>(rng() % static_cast<std::uint64_t>(m.positions.rows()));
    const auto i = static_cast<Eigen::Index>(rng() % 1024);
    const float c = m.normals.row(p).dot(d.row(i));
    if (c <= 0) continue;
    r.origins.push_back({m.positions(p, 0) + 1e-4f * m.normals(p, 0),
                         m.positions(p, 1) + 1e-4f * m.normals(p, 1),
                         m.positions(p, 2) + 1e-4f * m.normals(p, 2)});
    r.dirs.push_back({d(i, 0), d(i, 1), d(i, 2)});
  }
  return r;
}

void BM_OcclusionRays(benchmark::State& state) {
  const RayCaster caster(scene().positions, scene().triangles);
  const RaySet rays = hemisphere_rays(scene(), 1 << 16);
  size_t i = 0;
  long blocked = 0;
  for (auto _ : state) {
    blocked += caster.occluded(rays.origins[i], rays.dirs[i]);
    i = (i + 1) & ((1 << 16) - 1);
  }
  benchmark::DoNotOptimize(blocked);
  state.SetItemsProcessed(state.iterations());
  state.counters["triangles"] = static_cast<double>(scene().triangles.rows());
  state.counters["blocked"] = static_cast<double>(blocked) / static_cast<double>(state.iterations());
}

void BM_ClosestHitRays(benchmark::State& state) {
  const RayCaster caster(scene().positions, scene().triangles);
  const RaySet rays = hemisphere_rays(scene(), 1 << 16);
  size_t i = 0;
  long front = 0;
  for (auto _ : state) {
    front += caster.closest(rays.origins[i], rays.dirs[i]).front;
    i = (i + 1) & ((1 << 16) - 1);
  }
  benchmark::DoNotOptimize(front);
  state.SetItemsProcessed(state.iterations());
  state.counters["front_hits"] = static_cast<double>(front) / static_cast<double>(state.iterations());
}

// Transfer of every scene point at the default ray count (1024) and 2
// bounces; range(1) threads (0: all cores). items = scene points, so items/s
// inverts to seconds per point. Real time: the threads' work counts too.
void BM_TransferPerPoint(benchmark::State& state) {
  const auto mode = static_cast<TransferMode>(state.range(0));
  const TransferMesh& s = scene();
  TransferOptions o;
  o.mode = mode;
  o.threads = static_cast<int>(state.range(1));
  o.bounces = 2;
  for (auto _ : state) {
    const MatrixXfR T = compute_transfer(s.positions, s.triangles, s.normals, o);
    benchmark::DoNotOptimize(T.data());
  }
  state.SetItemsProcessed(state.iterations() * s.positions.rows());
  state.counters["points"] = static_cast<double>(s.positions.rows());
  state.counters["rays"] = o.rays;
  state.counters["threads"] =
      o.threads > 0 ? o.threads : static_cast<double>(std::thread::hardware_concurrency());
  state.SetLabel(transfer_mode_name(mode));
}

// Synthetic phase portrait: N state nodes in r_u = 20 dimensions, on a few
// smooth orbits (the k-means input of §4.3).
MatrixXfR portrait(int N) {
  MatrixXfR q(N, 20);
  for (int i = 0; i < N; ++i) {
    const double t = 0.01 * i;
    for (int d = 0; d < 20; ++d)
      q(i, d) = static_cast<float>(std::exp(-0.05 * d) * std::sin((d + 1) * t + d));
  }
  return q;
}

// k-means of N = range(0) nodes into N_a = 64 clusters.
void BM_KMeans(benchmark::State& state) {
  const MatrixXfR q = portrait(static_cast<int>(state.range(0)));
  for (auto _ : state) benchmark::DoNotOptimize(kmeans(q, {.clusters = 64, .seed = 1}).inertia);
  state.counters["N"] = static_cast<double>(q.rows());
}

// Transfer SVD + NRBF fit + leave-one-out + q_a at all nodes, for N_a = 64
// fields of the bench scene (S points) and N = 5000 nodes.
void BM_BuildAppearance(benchmark::State& state) {
  const MatrixXfR q = portrait(5000);
  const auto clusters = kmeans(q, {.clusters = 64, .seed = 1});
  const auto n = 48 * scene().positions.rows();
  MatrixXfR fields(64, n);
  std::mt19937_64 rng(3);
  for (Eigen::Index i = 0; i < fields.size(); ++i) {
    fields.data()[i] = static_cast<float>(static_cast<double>(rng() >> 11) * 0x1.0p-53);
  }
  for (auto _ : state) benchmark::DoNotOptimize(fit_appearance_model(q, clusters, fields, {}).q_a.data());
  state.counters["S"] = static_cast<double>(scene().positions.rows());
  state.counters["N_a"] = 64;
}

// Uniform random fields of the paper cloth's size (S = 16 374 scene points):
// N_a cluster fields and H reported held-out ones.
MatrixXfR random_fields(Eigen::Index rows, std::uint64_t seed) {
  MatrixXfR X(rows, 48 * 16374);
  std::mt19937_64 rng(seed);
  for (Eigen::Index i = 0; i < X.size(); ++i)
    X.data()[i] = static_cast<float>(static_cast<double>(rng() >> 11) * 0x1.0p-53);
  return X;
}

// The baseline of the next: the transfer SVD (§4.2) of N_a = range(0) fields at r_a = 12.
void BM_ReduceTransfer(benchmark::State& state) {
  const MatrixXfR fields = random_fields(state.range(0), 5);
  for (auto _ : state) benchmark::DoNotOptimize(reduce_transfer(fields, {.eps_a = 0, .rank = 12}).U_a.data());
  state.counters["N_a"] = static_cast<double>(fields.rows());
}

// Fig. 12 out of sample at every rank for H = range(0) / 2 held-out fields:
// the appearance stage's extra cost beside the SVD it measures.
void BM_HeldOutTruncationCurve(benchmark::State& state) {
  const MatrixXfR fields = random_fields(state.range(0), 5), held_out = random_fields(state.range(0) / 2, 6);
  const auto reduction = reduce_transfer(fields, {.eps_a = 0, .rank = 12});
  for (auto _ : state)
    benchmark::DoNotOptimize(held_out_truncation_curve(fields, reduction, held_out).data());
  state.counters["N_a"] = static_cast<double>(fields.rows());
  state.counters["H"] = static_cast<double>(held_out.rows());
}

// The NRBF's leave-one-out (§4.3, N_a refits of N_a - 1 samples) at N_a =
// range(0), r_u = 20, r_a = 12, on range(1) threads (0: all cores): the
// baseline is the same work on one thread. Run each case in a process of its
// own (--benchmark_filter=...threads:1, then threads:0): in one process the
// second case reads faster whichever it is (docs/performance.md).
void BM_NrbfLeaveOneOut(benchmark::State& state) {
  const Eigen::Index Na = state.range(0);
  const MatrixXfR centers = portrait(static_cast<int>(Na));
  MatrixXfR values(Na, 12);
  for (Eigen::Index i = 0; i < values.size(); ++i) values.data()[i] = static_cast<float>(std::sin(0.37 * i));
  const VectorXf widths = VectorXf::Constant(Na, 0.5f);
  const auto threads = state.range(1) > 0
                           ? static_cast<size_t>(state.range(1))
                           : tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism);
  const tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
  nrbf_leave_one_out(centers, widths, values,
                     1e-4f);  // warm: the first run in a process pays for its allocator
  for (auto _ : state) benchmark::DoNotOptimize(nrbf_leave_one_out(centers, widths, values, 1e-4f).relative);
  state.counters["N_a"] = static_cast<double>(Na);
  state.counters["threads"] = static_cast<double>(threads);
}

BENCHMARK(BM_OcclusionRays);
BENCHMARK(BM_ClosestHitRays);
BENCHMARK(BM_TransferPerPoint)
    ->ArgsProduct({{static_cast<int>(TransferMode::shadowed), static_cast<int>(TransferMode::interreflected)},
                   {1, 0}})
    ->ArgNames({"mode", "threads"})
    ->Unit(benchmark::kSecond)
    ->UseRealTime()
    ->Iterations(1);
BENCHMARK(BM_KMeans)->Arg(5000)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_BuildAppearance)->Unit(benchmark::kSecond)->Iterations(1);
BENCHMARK(BM_ReduceTransfer)->Arg(200)->Unit(benchmark::kSecond)->Iterations(1);
BENCHMARK(BM_HeldOutTruncationCurve)->Arg(200)->Unit(benchmark::kSecond)->Iterations(1);
BENCHMARK(BM_NrbfLeaveOneOut)
    ->ArgsProduct({{200}, {0, 1}})
    ->ArgNames({"N_a", "threads"})
    ->Unit(benchmark::kSecond)
    ->UseRealTime()
    ->Iterations(1);

}  // namespace
}  // namespace phasecast::precompute

int main(int argc, char** argv) {
  for (int i = 1; i < argc; ++i) {
    if (std::strncmp(argv[i], "--grid=", 7) == 0) phasecast::precompute::g_grid = std::stoi(argv[i] + 7);
  }
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
