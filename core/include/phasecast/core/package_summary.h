#pragma once
// What phasecast-inspect reports about a package: counts, ranks, errors,
// sizes, and what a thin client must download.

#include "phasecast/core/package.h"

#include <nlohmann/json_fwd.hpp>

#include <cstdint>
#include <filesystem>
#include <optional>
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
  std::optional<HeldOutFigures> held_out;       // absent: no held-out truth in the package
  std::optional<PlaybackFidelity> fidelity;     // absent: playback not measured when it was made
  std::uint64_t client_download_bytes = 0;      // sum of basis parts
  std::uint64_t frame_state_bytes = 0;          // q_u + q_a + support per frame
  std::uint64_t full_vertex_frame_bytes = 0;    // streaming vertices instead
};

// `rank` <= 0 reports the error at the package's r_u.
PackageSummary summarize(const ScenePackage& package, const std::filesystem::path& file, int rank = 0);

std::string to_text(const PackageSummary& s);
// The held-out truncation curve at ranks 1, 2, 4, 8, ..., r_a, the paper's
// r_a and all K, and the first rank at which it reaches `in_sample`: the
// clusters' own truncation at r_a over as many of them as there are reported
// nodes (HeldOutFigures::clusters_l2_truncation; NaN: not said). Empty for an
// empty curve.
std::string held_out_curve_text(const std::vector<double>& curve, int rank_a, int paper_rank_a,
                                double in_sample);
nlohmann::json to_json(const PackageSummary& s);

}  // namespace phasecast::core
