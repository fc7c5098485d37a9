// bench_solvers: the linear solve of one implicit cloth step at the paper's
// size (scenes/paper/cloth_door.toml, 3 332 vertices, ~10 000 free DOF), by
// each candidate: Eigen's simplicial LDL^T (the baseline), CHOLMOD's
// supernodal Cholesky, and conjugate gradients (Jacobi preconditioner,
// warm-started from the previous step's solution, as a Newton loop would).
// The matrix is A = M + (h b + h^2) K at a perturbed state, as the simulator
// assembles it; each iteration refactorizes with the pattern analysed once.

#include "bench_scenes.h"
#include "phasecast/precompute/simulation/elastic_forces.h"
#include "phasecast/precompute/simulation/scene.h"

#include <benchmark/benchmark.h>

#include <Eigen/CholmodSupport>
#include <Eigen/IterativeLinearSolvers>
#include <Eigen/SparseCholesky>

#include <random>

namespace {

using phasecast::precompute::load_scene_file;

const std::filesystem::path kScenes = phasecast::bench::scenes_dir();

struct System {
  Eigen::SparseMatrix<double> A;
  Eigen::VectorXd b;
};

System paper_cloth_system() {
  const auto scene = load_scene_file(kScenes / "paper/cloth_door.toml");
  const auto& m = scene.model;
  std::mt19937 rng(7);
  std::normal_distribution<double> n(0, 0.003);
  Eigen::VectorXd x = m.rest;
  for (Eigen::Index i = 0; i < x.size(); ++i) x[i] += n(rng);
  const auto el = evaluate_elastic(m, x, true);
  const double h = scene.simulation.frame_dt / scene.simulation.substeps;
  const double k_scale = h * scene.simulation.stiffness_damping + h * h;
  std::vector<int> free(static_cast<size_t>(x.size()), -1);
  int count = 0;
  for (int v = 0; v < m.vertices(); ++v)
    if (!m.pinned[static_cast<size_t>(v)])
      for (int k = 0; k < 3; ++k) free[static_cast<size_t>(3 * v + k)] = count++;
  std::vector<Eigen::Triplet<double>> t;
  for (const auto& e : el.stiffness) {
    const int r = free[static_cast<size_t>(e.row())], c = free[static_cast<size_t>(e.col())];
    if (r >= 0 && c >= 0) t.emplace_back(r, c, k_scale * e.value());
  }
  System s;
  s.b = Eigen::VectorXd::Zero(count);
  for (int v = 0; v < m.vertices(); ++v) {
    for (int k = 0; k < 3; ++k) {
      const int r = free[static_cast<size_t>(3 * v + k)];
      if (r < 0) continue;
      t.emplace_back(r, r, m.mass[v]);
      s.b[r] = h * (el.force[3 * v + k] + m.mass[v] * (k == 1 ? -9.81 : 0.0));
    }
  }
  s.A.resize(count, count);
  s.A.setFromTriplets(t.begin(), t.end());
  s.A.makeCompressed();
  return s;
}

const System& system() {
  static const System s = paper_cloth_system();
  return s;
}

template <class Solver>
void direct(benchmark::State& state) {
  const auto& s = system();
  Solver solver;
  solver.analyzePattern(s.A);
  Eigen::VectorXd x;
  for (auto _ : state) {
    solver.factorize(s.A);
    x = solver.solve(s.b);
    benchmark::DoNotOptimize(x.data());
  }
  state.counters["dof"] = static_cast<double>(s.A.rows());
  state.counters["residual"] = (s.A * x - s.b).norm() / s.b.norm();
}

void BM_SimplicialLDLT(benchmark::State& st) {
  direct<Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>>>(st);
}
void BM_CholmodSupernodalLLT(benchmark::State& st) {
  direct<Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>>>(st);
}

// Warm start: each solve starts from the solution of a right-hand side 1 %
// different, the way successive Newton iterations and substeps do.
void BM_ConjugateGradientJacobi(benchmark::State& state) {
  const auto& s = system();
  Eigen::ConjugateGradient<Eigen::SparseMatrix<double>, Eigen::Lower | Eigen::Upper> cg;
  cg.setTolerance(1e-8);
  cg.compute(s.A);
  const Eigen::VectorXd previous = cg.solve(0.99 * s.b);
  Eigen::VectorXd x;
  int iterations = 0;
  for (auto _ : state) {
    cg.compute(s.A);
    x = cg.solveWithGuess(s.b, previous);
    iterations = static_cast<int>(cg.iterations());
    benchmark::DoNotOptimize(x.data());
  }
  state.counters["dof"] = static_cast<double>(s.A.rows());
  state.counters["iterations"] = iterations;
  state.counters["residual"] = (s.A * x - s.b).norm() / s.b.norm();
}

BENCHMARK(BM_SimplicialLDLT)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_CholmodSupernodalLLT)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_ConjugateGradientJacobi)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
