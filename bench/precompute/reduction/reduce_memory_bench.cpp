// Peak memory and time of the displacement reduction (§2.3.1) at a given size
// 3V x N (issue 17: the SVD stage reads the orbit store in blocks and holds
// O((3V + N) r) plus one block, never A_u). Either a real orbit store, or a
// synthetic one of the paper scenes' sizes written block by block (the values
// do not change the memory: the same code reads and reduces them).
//
//   phasecast-bench-reduce-memory --rows 9996 --cols 13059           synthetic, paper cloth size
//   phasecast-bench-reduce-memory --store cloth.h5.work/orbits.h5    a sampled store
//
// Prints the peak resident memory the reduction added to the process, next to
// the size of A_u and to the model (one block + the panels).

#include "phasecast/core/hdf5_file.h"
#include "phasecast/core/process_memory.h"
#include "phasecast/precompute/reduction/displacement_reduction.h"

#include <fmt/format.h>
#include "phasecast/core/command_line.h"

#include <CLI/CLI.hpp>

#include <unistd.h>

#include <chrono>
#include <cmath>
#include <random>

namespace {

using phasecast::MatrixXfR;
using phasecast::precompute::DisplacementBasis;
using phasecast::precompute::OrbitDisplacementSource;
using phasecast::precompute::RandomizedSvdOptions;
using phasecast::precompute::ReductionOptions;

// Frames of a rest shape plus `modes` random smooth motions, written 256 at a time.
void write_synthetic_store(const std::filesystem::path& path, Eigen::Index rows, Eigen::Index cols,
                           int modes) {
  namespace h5 = phasecast::core::h5;
  h5::File f = h5::File::create(path);
  f.create_rows<float>("/frames/positions", {static_cast<std::uint64_t>(rows)});
  std::mt19937 rng(7);
  std::normal_distribution<float> g;
  Eigen::MatrixXf shapes(rows, modes + 1);
  for (Eigen::Index i = 0; i < shapes.size(); ++i) shapes.data()[i] = g(rng);
  constexpr Eigen::Index kChunk = 256;
  MatrixXfR frames;
  for (Eigen::Index first = 0; first < cols; first += kChunk) {
    const Eigen::Index n = std::min(kChunk, cols - first);
    Eigen::MatrixXf weights(modes + 1, n);
    for (Eigen::Index k = 0; k < n; ++k) {
      weights(0, k) = 1;
      for (int m = 1; m <= modes; ++m)
        weights(m, k) = std::sin(0.01f * static_cast<float>((first + k) * m)) / static_cast<float>(m);
    }
    frames = (shapes * weights).transpose();
    f.append_rows("/frames/positions", frames.data(), static_cast<std::uint64_t>(n));
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "Peak memory and time of the streamed displacement reduction (randomized SVD of an orbit store)."};
  std::string store;
  Eigen::Index rows = 9996, cols = 13059;
  int modes = 40;
  ReductionOptions options;
  app.add_option("--store", store, "a sampled orbit store (.h5) instead of a synthetic one");
  app.add_option("--rows", rows, "3V of the synthetic store")->capture_default_str();
  app.add_option("--cols", cols, "N, its state nodes")->capture_default_str();
  app.add_option("--modes", modes, "smooth motions in the synthetic frames")->capture_default_str();
  app.add_option("--max-rank", options.max_rank, "singular triplets computed")->capture_default_str();
  if (const auto status =
          phasecast::core::parse_command_line(app, argc, argv, "phasecast-bench-reduce-memory"))
    return *status;

  std::filesystem::path path = store;
  if (store.empty()) {
    path = std::filesystem::temp_directory_path() / fmt::format("phasecast-reduce-memory-{}.h5", ::getpid());
    write_synthetic_store(path, rows, cols, modes);
  }
  phasecast::core::reset_peak_resident_memory();
  const double before = phasecast::core::resident_memory().current_mib;
  const auto start = std::chrono::steady_clock::now();
  DisplacementBasis basis;
  Eigen::Index M = 0, N = 0;
  {
    const OrbitDisplacementSource A(path);
    M = A.rows();
    N = A.cols();
    basis = phasecast::precompute::reduce_displacements(A, options);
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const double added = phasecast::core::resident_memory().peak_mib - before;
  if (store.empty()) std::filesystem::remove(path);

  const double mib = 1.0 / (1 << 20);
  const Eigen::Index l = options.max_rank + options.oversampling;
  const double block = static_cast<double>(phasecast::precompute::block_columns(RandomizedSvdOptions{}, M)) *
                       static_cast<double>(M) * sizeof(float) * mib;
  const double panels = static_cast<double>(M + N) * static_cast<double>(l) * sizeof(float) * mib;
  fmt::print("{} store, 3V x N = {} x {}, l = {}: A_u would be {:.0f} MiB\n",
             store.empty() ? "synthetic" : "sampled", M, N, l,
             static_cast<double>(M) * static_cast<double>(N) * sizeof(float) * mib);
  fmt::print(
      "reduction: {:.1f} s, peak resident memory +{:.0f} MiB (one block {:.0f} MiB, (3V + N) l floats {:.0f} "
      "MiB)\n",
      seconds, added, block, panels);
  fmt::print("relErr sigma_31/sigma_1 = {:.4g}\n",
             basis.singular_values.size() > 30 ? basis.singular_values[30] / basis.singular_values[0] : 0.0f);
  return 0;
}
