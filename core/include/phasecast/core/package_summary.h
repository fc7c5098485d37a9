#pragma once
// What phasecast-inspect reports about a package: counts, ranks, errors,
// sizes, and what a thin client must download.

#include "phasecast/core/package.h"

#include <nlohmann/json_fwd.hpp>

#include <cstdint>
#include <filesystem>
#include <string>

namespace phasecast::core {

struct PackageSummary {
  std::string file;
  std::string scene;
  std::uint64_t file_bytes = 0;
  std::uint64_t content_hash = 0;
  int points = 0, deformable_points = 0, triangles = 0;  // S, deformable part of S, F
  int state_nodes = 0, irfs = 0, palette_entries = 0;    // N, n_irf, D
  std::vector<std::string> palette;
  std::vector<int> irfs_per_entry;           // D
  double dt = 0, duration_s = 0;             // N * dt
  int rank_u = 0, rank_a = 0, clusters = 0;  // r_u, r_a, N_a
  int chosen_rank = 0;                       // rank the error is reported at
  double error_u_at_rank = 0;                // Frobenius: |X - X_r|_F / |X|_F (Fig. 12, blue)
  double sigma_ratio_u_at_rank = 0;          // the paper's relErr (§2.3.1): sigma_{r+1}/sigma_1, or NaN
  std::vector<double> singular_values_u;     // every computed sigma of the displacements
  double error_a_at_rank = 0;                // at r_a (Fig. 12, red); NaN without appearance
  std::vector<double> error_a_curve;         // Fig. 12, red: relative error at rank 1..N_a
  int paper_rank_a = 0;                      // the paper's r_a for this scene (0: unknown)
  double error_a_at_paper_rank = 0;          // NaN when unknown or above N_a
  // The paper's relErr of the appearance (§2.3.1, Table 1): sigma_{r+1}/sigma_1
  // of A_a, at r_a and at the paper's r_a; NaN when not computed.
  double sigma_ratio_a_at_rank = 0, sigma_ratio_a_at_paper_rank = 0;
  std::vector<double> singular_values_a;  // every sigma of A_a (N_a)
  std::string interpolant;                // its name ("nrbf", "knn", "affine-knn(-slope)") and parameters
  std::string transfer_weighting;         // "equal" or "cluster size"
  int transfer_rays = 0, transfer_bounces = 0;  // how the transfer was sampled (0 rays: unrecorded)
  int held_out_nodes = 0;                       // 0: no held-out truth in the package
  double held_out_total = 0, held_out_truncation = 0, held_out_interpolation = 0, held_out_of_transfer = 0;
  // The same in the paper's relErr: relative l2 (spectral) norms; NaN in older packages.
  double held_out_l2_total = 0, held_out_l2_truncation = 0;
  // The clusters' own truncation in that norm over as many of them as there are
  // held-out nodes: what held_out_l2_truncation compares with. NaN in older packages.
  double clusters_l2_truncation_at_held_out_size = 0;
  // The least relative l2 error any rank-r_a model about this M-bar has at
  // the held-out nodes (sigma_{r_a+1} / sigma_1 of their truth less M-bar):
  // what no basis or interpolant about it can beat. NaN in older packages.
  double held_out_l2_floor = 0;
  // The total relative to the held-out nodes' variation about their own mean
  // (Frobenius, relative l2), a denominator no model moves, and the least
  // relative l2 any rank-r_a model has there, whatever its mean. NaN in older packages.
  double held_out_of_variation = 0, held_out_l2_of_variation = 0, held_out_l2_floor_of_variation = 0;
  // 10th and 90th percentiles of held_out_l2_total, then of held_out_l2_truncation,
  // then of held_out_l2_of_variation, over bootstrap resamples of the held-out
  // nodes; empty (or without the last two) in older packages.
  std::vector<double> held_out_l2_spread;
  // Fig. 12's red curve out of sample: the held-out truncation as a relative
  // l2 norm at rank 1..K of the clusters' SVD; empty in older packages.
  std::vector<double> held_out_l2_truncation_curve;
  std::uint64_t client_download_bytes = 0;    // sum of basis parts
  std::uint64_t frame_state_bytes = 0;        // q_u + q_a + support per frame
  std::uint64_t full_vertex_frame_bytes = 0;  // streaming vertices instead
};

// `rank` <= 0 reports the error at the package's r_u.
PackageSummary summarize(const ScenePackage& package, const std::filesystem::path& file, int rank = 0);

std::string to_text(const PackageSummary& s);
// The held-out truncation curve at ranks 1, 2, 4, 8, ..., r_a, the paper's
// r_a and all K, and the first rank at which it reaches `in_sample`: the
// clusters' own truncation at r_a over as many of them as there are reported
// nodes (held_out_error[6]; NaN: not said). Empty for an empty curve.
std::string held_out_curve_text(const std::vector<double>& curve, int rank_a, int paper_rank_a,
                                double in_sample);
nlohmann::json to_json(const PackageSummary& s);

}  // namespace phasecast::core
