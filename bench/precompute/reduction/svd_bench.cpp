// Randomized vs full SVD on the same matrix, in the same run: time ratio and
// error ratio (issue: output-sensitive SVD of §2.3.1).
//
//   phasecast-bench-svd [--rows M] [--cols N] [--rank r] [--decay d]
//
// The matrix has the slowly decaying spectrum of cloth orbits (sigma_i ~ d^i
// plus a noise floor); with an orbit store the precompute benchmark uses the
// real displacement matrix instead.

#include "phasecast/precompute/reduction/randomized_svd.h"

#include <fmt/format.h>
#include "phasecast/core/command_line.h"

#include <CLI/CLI.hpp>
#include <Eigen/QR>
#include <Eigen/SVD>

#include <chrono>
#include <random>

namespace {

using Clock = std::chrono::steady_clock;

Eigen::MatrixXf orbit_like_matrix(Eigen::Index M, Eigen::Index N, double decay) {
  std::mt19937 rng(5);
  std::normal_distribution<float> n;
  const Eigen::Index k = std::min<Eigen::Index>(std::min(M, N), 200);
  Eigen::MatrixXf G(M, k), H(N, k);
  for (Eigen::Index i = 0; i < G.size(); ++i) G.data()[i] = n(rng);
  for (Eigen::Index i = 0; i < H.size(); ++i) H.data()[i] = n(rng);
  const Eigen::MatrixXf U =
      Eigen::HouseholderQR<Eigen::MatrixXf>(G).householderQ() * Eigen::MatrixXf::Identity(M, k);
  const Eigen::MatrixXf V =
      Eigen::HouseholderQR<Eigen::MatrixXf>(H).householderQ() * Eigen::MatrixXf::Identity(N, k);
  Eigen::VectorXf s(k);
  for (Eigen::Index i = 0; i < k; ++i)
    s[i] = static_cast<float>(std::pow(decay, static_cast<double>(i)) + 1e-4);
  return U * s.asDiagonal() * V.transpose();
}

double seconds_since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Randomized (streaming) vs full SVD on one matrix: time and error ratios."};
  Eigen::Index M = 6000, N = 2000;
  int rank = 30;
  double decay = 0.9;
  app.add_option("--rows", M, "rows M = 3V")->capture_default_str();
  app.add_option("--cols", N, "columns N (state nodes)")->capture_default_str();
  app.add_option("--rank", rank, "rank r")->capture_default_str();
  app.add_option("--decay", decay, "singular value decay per index")->capture_default_str();
  if (const auto status = phasecast::core::parse_command_line(app, argc, argv, "phasecast-bench-svd"))
    return *status;

  const Eigen::MatrixXf A = orbit_like_matrix(M, N, decay);
  const double norm = A.norm();

  auto t0 = Clock::now();
  phasecast::precompute::RandomizedSvdOptions o;
  o.rank = rank;
  const auto r = phasecast::precompute::randomized_svd(phasecast::precompute::MatrixColumnSource(A), o);
  const double t_rand = seconds_since(t0);
  const double e_rand = (A - r.U * r.sigma.asDiagonal() * r.V.transpose()).norm() / norm;

  t0 = Clock::now();
  const Eigen::BDCSVD<Eigen::MatrixXf> full(A, Eigen::ComputeThinU | Eigen::ComputeThinV);
  const double t_full = seconds_since(t0);
  const Eigen::MatrixXf best = full.matrixU().leftCols(rank) * full.singularValues().head(rank).asDiagonal() *
                               full.matrixV().leftCols(rank).transpose();
  const double e_full = (A - best).norm() / norm;

  fmt::print("matrix {}x{}, rank {}\n", M, N, rank);
  fmt::print("{:<28} {:>10} {:>14}\n", "method", "seconds", "rel. error");
  fmt::print("{:<28} {:>10.3f} {:>14.6g}\n", "randomized (q=2, p=10)", t_rand, e_rand);
  fmt::print("{:<28} {:>10.3f} {:>14.6g}\n", "full (Eigen BDCSVD)", t_full, e_full);
  fmt::print("time ratio full/randomized = {:.1f}x, error ratio randomized/full = {:.4f}\n", t_full / t_rand,
             e_rand / e_full);
  return 0;
}
