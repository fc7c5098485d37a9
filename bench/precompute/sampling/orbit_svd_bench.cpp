// Randomized SVD streamed from an orbit store on disk vs Eigen's full BDCSVD of
// the same displacement matrix held in memory, in the same run: time ratio and
// error ratio at the same rank (issue 4, item 9).
//
//   phasecast-bench-orbit-svd ORBITS.h5 [--rank r] [--power-iterations q]
//
// ORBITS.h5 is an orbit store, e.g. <package>.work/orbits.h5 left by
// 'phasecast-precompute run'.

#include "phasecast/precompute/reduction/displacement_reduction.h"

#include <fmt/format.h>
#include "phasecast/core/command_line.h"

#include <CLI/CLI.hpp>
#include <Eigen/SVD>

#include <chrono>
#include <exception>

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

void run(const std::string& path, int rank, int power_iterations) {
  using namespace phasecast::precompute;
  auto t0 = Clock::now();
  const OrbitDisplacementSource source(path);  // includes the mean-shape pass
  RandomizedSvdOptions o;
  o.rank = rank;
  o.power_iterations = power_iterations;
  const SvdResult r = randomized_svd(source, o);
  const double t_rand = seconds_since(t0);

  t0 = Clock::now();
  Eigen::MatrixXf A;
  source.read(0, source.cols(), A);
  const double t_load = seconds_since(t0);
  t0 = Clock::now();
  const Eigen::BDCSVD<Eigen::MatrixXf> full(A, Eigen::ComputeThinU | Eigen::ComputeThinV);
  const double t_full = seconds_since(t0);

  const double norm = A.norm();
  const double e_rand = (A - r.U * r.sigma.asDiagonal() * r.V.transpose()).norm() / norm;
  const int k = static_cast<int>(r.sigma.size());
  const Eigen::MatrixXf best = full.matrixU().leftCols(k) * full.singularValues().head(k).asDiagonal() *
                               full.matrixV().leftCols(k).transpose();
  const double e_full = (A - best).norm() / norm;
  fmt::print("orbit matrix {} x {} (3V x N) from {}, rank {}\n", A.rows(), A.cols(), path, k);
  fmt::print("{:<36} {:>10} {:>14}\n", "method", "seconds", "rel. error");
  fmt::print("{:<36} {:>10.3f} {:>14.6g}\n",
             fmt::format("randomized, streamed (q={}, p=10)", power_iterations), t_rand, e_rand);
  fmt::print("{:<36} {:>10.3f} {:>14.6g}\n", "full (Eigen BDCSVD, in memory)", t_full, e_full);
  fmt::print("(loading the matrix for the full SVD took {:.3f} s more)\n", t_load);
  fmt::print("time ratio full/randomized = {:.1f}x, error ratio randomized/full = {:.4f}\n", t_full / t_rand,
             e_rand / e_full);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Randomized (streamed from disk) vs full SVD of a real orbit matrix: time and error ratios."};
  std::string path;
  int rank = 30, power_iterations = 2;
  app.add_option("orbits", path, "orbit store (.h5)")->required();
  app.add_option("--rank", rank, "rank r")->capture_default_str();
  app.add_option("--power-iterations", power_iterations, "q")->capture_default_str();
  if (const auto status = phasecast::core::parse_command_line(app, argc, argv, "phasecast-bench-orbit-svd"))
    return *status;
  try {
    run(path, rank, power_iterations);
  } catch (const std::exception& e) {
    fmt::print(stderr, "phasecast-bench-orbit-svd: {}\n", e.what());
    return 1;
  }
  return 0;
}
