// The IRF reference cache (§5.2) at the scale: N = 20 000 nodes, D = 5
// entries, compared against a brute-force eq. 9 search on a sample of nodes.
//
//   phasecast-bench-irf-cache [--nodes N] [--entries D] [--rank r] [--irfs n]

#include "phasecast/precompute/reduction/phase_portrait.h"

#include <fmt/format.h>
#include "phasecast/core/command_line.h"

#include <CLI/CLI.hpp>

#include <chrono>
#include <limits>
#include <random>

int main(int argc, char** argv) {
  CLI::App app{"Nearest-IRF cache (eq. 9) timing at N = 20 000, D = 5, checked against brute force."};
  int N = 20000, D = 5, r = 30, n_irf = 1000;
  app.add_option("--nodes", N, "state nodes N")->capture_default_str();
  app.add_option("--entries", D, "palette entries D")->capture_default_str();
  app.add_option("--rank", r, "r_u")->capture_default_str();
  app.add_option("--irfs", n_irf, "IRFs (equal lengths)")->capture_default_str();
  if (const auto status = phasecast::core::parse_command_line(app, argc, argv, "phasecast-bench-irf-cache"))
    return *status;
  if (N < 1 || D < 1 || r < 1 || n_irf < 1 || n_irf > N) {
    fmt::print(stderr, "phasecast-bench-irf-cache: expected N, D, r >= 1 and 1 <= IRFs <= N\n");
    return 1;
  }
  std::mt19937 rng(3);
  std::normal_distribution<float> g;
  phasecast::MatrixXfR q(N, r), qdot(N, r);
  for (Eigen::Index i = 0; i < q.size(); ++i) {
    q.data()[i] = g(rng);
    qdot.data()[i] = g(rng);
  }
  std::vector<std::int32_t> start, palette;
  for (int i = 0; i < n_irf; ++i) {
    start.push_back(static_cast<std::int32_t>(static_cast<long long>(i) * N / n_irf));
    palette.push_back(i % D);
  }
  const auto t0 = std::chrono::steady_clock::now();
  const std::vector<std::int32_t> length(start.size(), static_cast<std::int32_t>(N / n_irf));
  const auto cache = phasecast::precompute::nearest_irf_cache(q, qdot, 0.5, start, length, palette, D);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  int mismatches = 0;
  for (int j = 0; j < N; j += 997) {
    for (int d = 0; d < D; ++d) {
      double best = std::numeric_limits<double>::infinity();
      int arg = -1;
      for (int i = 0; i < n_irf; ++i) {
        if (palette[static_cast<size_t>(i)] != d) continue;
        const auto s = start[static_cast<size_t>(i)];
        const double dist = (q.row(j) - q.row(s)).cast<double>().squaredNorm() +
                            0.5 * (qdot.row(j) - qdot.row(s)).cast<double>().squaredNorm();
        if (dist < best) {
          best = dist;
          arg = i;
        }
      }
      mismatches += cache(j, d) != arg;
    }
  }
  fmt::print(
      "nearest_irf_cache: N = {}, D = {}, r_u = {}, {} IRFs: {:.3f} s; brute-force mismatches on {} sampled "
      "nodes: {}\n",
      N, D, r, n_irf, seconds, (N + 996) / 997, mismatches);
  return mismatches == 0 ? 0 : 1;
}
