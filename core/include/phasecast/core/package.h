#pragma once
// The scene package: everything precompute produces and the server and
// clients consume, in one HDF5 file. docs/package-format.md is the normative
// description of every dataset; the names here follow it and the paper.

#include "phasecast/core/eigen_types.h"
#include "phasecast/core/sh.h"

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace phasecast::core {

// The version write_package() writes; read_package() also reads every older
// one (docs/package-format.md, "Older versions").
inline constexpr int kFormatVersion = 2;
inline constexpr int kTransferPerPoint = kShChannels * kShCoefficients;  // 48 per scene point
inline constexpr int kKinematicsColumns = 11;                            // columns of /palette/kinematics
inline constexpr int kSupportFloats = 12;                                // 3x4 support transform

// End-of-IRF rule of a palette entry (/palette/on_end): -1, -2, or a follow-up index.
inline constexpr std::int32_t kEndRest = -1;
inline constexpr std::int32_t kEndHold = -2;

// Thrown for every invalid package: the message is one line naming the file,
// the dataset and what was expected.
class PackageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// The SH light probes a package's `light` may name, the clients' own
// (client/scene sh_light.h light_probe builds them).
inline constexpr std::array<const char*, 4> kLightProbeNames{"grace", "sky", "sun", "white"};

// Root attributes.
struct PackageAttributes {
  int format_version = kFormatVersion;
  std::string scene;
  double dt = 0;                                // seconds per state-node time step
  double beta = 1;                              // velocity weight of the distance metric (eq. 9)
  double blend_lambda = 1;                      // IRF blend decay rate, 1/s (eq. 12)
  double eps_u = 0;                             // displacement rank tolerance (§2.3.1)
  double eps_a = 0;                             // appearance rank tolerance (§4.2)
  std::optional<std::array<float, 10>> camera;  // eye(3) target(3) up(3) fov_y_deg
  // The rest of the scene's [view] (docs/scenes.md): clients use each where
  // their own flags are absent.
  bool floor = true;                  // false: no floor ([view] floor = "none")
  std::optional<float> floor_height;  // y of the floor; absent: the rest mesh's lowest point
  std::string light;                  // SH light probe; empty: the client's default
  std::optional<float> exposure;      // absent: the client's default (1)
};

// Scene points: deformable and static, double-sided surfaces duplicated.
struct SceneMesh {
  MatrixXfR rest_positions;              // S x 3, metres, support frame
  MatrixXuR triangles;                   // F x 3 point indices
  MatrixXfR normals;                     // S x 3 unit rest normals
  std::vector<std::uint8_t> deformable;  // S: 1 = moved by U_u
  std::vector<std::uint8_t> attached;    // S: 1 = moves with the support transform

  int points() const { return static_cast<int>(rest_positions.rows()); }
  int triangle_count() const { return static_cast<int>(triangles.rows()); }
};

// Support motion while a palette entry is active. Entries with pulse_tau == 0
// drive the scene's support coordinate s (angle or offset along `axis`) at
// `rate`, clamped to [range_min, range_max]; entries with pulse_tau > 0 are
// jolts: a transient displacement pulse that returns to rest.
struct SupportKinematics {
  std::array<float, 3> axis{0, 1, 0};
  std::array<float, 3> pivot{0, 0, 0};
  bool rotational = false;
  float rate = 0;
  float range_min = 0;
  float range_max = 0;
  float pulse_tau = 0;
};

// The run of IRFs of one palette group started in a row (an instance's or a
// sampled chain's history, as far as max_in_a_row needs it). length 0: none.
struct PaletteRun {
  std::int32_t group = 0;
  std::uint32_t length = 0;
};

// The two history rules shared by the sampler (PaletteRules) and the server,
// so that the server refuses exactly what was never sampled.
// Whether starting entry `to` keeps `run` within max_in_a_row[to] (0: any).
bool within_run_limit(const std::vector<std::int32_t>& group, const std::vector<std::int32_t>& max_in_a_row,
                      const PaletteRun& run, int to);
// The run after entry `to` starts: one longer in the same group, else 1.
PaletteRun extended_run(const std::vector<std::int32_t>& group, const PaletteRun& run, int to);
// Whole frames of motion left to a support driven at `rate` from coordinate
// `s` within [range_min, range_max] (a door at 60 degrees opens 30 more);
// `max_frames` when the range is unlimited (min == max) or the rate is 0.
int frames_of_support_motion(double rate, double range_min, double range_max, double s, double dt,
                             int max_frames);

// The D entries of the impulse palette (§3.3) with their transition rules: a
// small state machine of (last entry, run of one group, support coordinate).
struct ImpulsePalette {
  std::vector<std::string> names;             // D
  MatrixXfR alpha_impulse;                    // D x k  (alpha^I)
  MatrixXfR alpha_forcing;                    // D x k  (alpha^F)
  MatrixXbR transitions;                      // (D+1) x D: row 0 from rest, row i+1 from entry i
  std::vector<std::int32_t> on_end;           // D: kEndRest, kEndHold or follow-up index
  std::vector<SupportKinematics> kinematics;  // D
  std::vector<std::int32_t> group;            // D: group of each entry (its first entry's index)
  std::vector<std::int32_t> max_in_a_row;     // D: at most this many of the group in a row (0: any)

  int size() const { return static_cast<int>(names.size()); }
  // Index of the entry called `name`, or -1.
  int index_of(const std::string& name) const;
  // Whether entry `to` may follow entry `from` (-1: from rest).
  bool allowed(int from, int to) const;
  // Whether starting entry `to` keeps the run within `to`'s max_in_a_row.
  bool within_run_limit(const PaletteRun& run, int to) const;
  // The run after entry `to` starts: one longer in the same group, else 1.
  PaletteRun extended(const PaletteRun& run, int to) const;
  // Whether entry `to` can move the support from coordinate `s` by at least
  // one frame of `dt` within the range (§3.5: a door at its stop cannot open
  // further); entries that hold the support still or jolt it always can.
  bool can_move_support(int to, double s, double dt) const;
};

// Displacement model reduction (§2.3.1, eqs. 3-7).
struct Reduction {
  VectorXf mean_shape;       // 3S: x-bar; static points keep their rest position
  MatrixXfR U_u;             // 3S x r_u: W times the orthonormal SVD basis (static rows 0)
  VectorXf singular_values;  // every computed sigma, decreasing
  VectorXf rel_error;        // same length: relative l2 reconstruction error at rank i+1 (Fig. 12)

  int rank() const { return static_cast<int>(U_u.cols()); }
};

// The reduced discrete phase portrait (§2.3.2) and the IRF reference cache (§5.2).
struct PhasePortrait {
  MatrixXfR q_u;                          // N x r_u reduced displacement coordinates (eq. 6)
  MatrixXfR qdot_u;                       // N x r_u reduced velocities (eq. 8)
  MatrixXfR q_a;                          // N x r_a reduced appearance coordinates (0 columns: none)
  std::vector<std::int32_t> irf_start;    // n_irf: first state node of each IRF
  std::vector<std::int32_t> irf_length;   // n_irf: number of state nodes
  std::vector<std::int32_t> irf_palette;  // n_irf: palette entry that started it
  MatrixXiR nearest_irf;                  // N x D: nearest IRF of each entry under eq. 9
  MatrixXfR support;                      // N x 12 support transform as simulated (0 rows: absent)

  int nodes() const { return static_cast<int>(q_u.rows()); }
  int irf_count() const { return static_cast<int>(irf_start.size()); }
};

// The 10th and 90th percentiles of a figure over bootstrap resamples of the
// held-out nodes.
struct Percentiles {
  float p10 = 0, p90 = 0;
};

// The appearance model measured at held-out state nodes (docs/transfer.md,
// "Held-out truth"), each a dataset under /appearance/held_out/. The four
// plain figures are always measured; the optional ones may be absent from
// packages measured before them, and the figures about the nodes' own
// variation need at least two nodes.
struct HeldOutFigures {
  std::vector<std::int32_t> nodes;  // the reported held-out state nodes
  // RMS over the nodes relative to |M - M-bar|; total² = truncation² + interpolation².
  float total = 0, truncation = 0, interpolation = 0;
  float of_transfer = 0;  // total relative to |M|
  // Relative l2 norms, the paper's relErr: total and truncation alone.
  std::optional<float> l2_total, l2_truncation;
  // The clusters' own relative l2 truncation over as many clusters as there
  // are held-out nodes: what l2_truncation compares with.
  std::optional<float> clusters_l2_truncation;
  // The least relative l2 any rank-r_a model about M-bar reaches at the nodes.
  std::optional<float> l2_floor;
  // The total relative to the nodes' variation about their own mean
  // (Frobenius, relative l2), and the least relative l2 any rank-r_a model
  // about that mean reaches.
  std::optional<float> of_variation, l2_of_variation, l2_floor_of_variation;
  std::optional<Percentiles> l2_total_spread, l2_truncation_spread, l2_of_variation_spread;
  // Fig. 12's red curve out of sample: the nodes' relative l2 truncation at
  // rank 1..K of the SVD U_a was cut from (K the directions it resolves).
  // Entry r_a - 1 is l2_truncation; the last is what the clusters' whole span
  // leaves. Empty: not measured.
  VectorXf truncation_curve;
};

// Reduced radiance transfer (§4).
struct Appearance {
  VectorXf mean_transfer;  // 48S: M-bar
  MatrixXfR U_a;           // 48S x r_a orthonormal transfer basis
  // Of the paper's A_a (equal weights) whichever weighting made U_a, so the
  // paper's relErr and Fig. 12 read the same in every package.
  VectorXf singular_values;                 // every computed sigma, decreasing
  VectorXf rel_error;                       // relative l2 error at rank i+1 (Fig. 12, red)
  std::vector<std::int32_t> cluster_nodes;  // N_a state nodes whose transfer was computed
  MatrixXfR nrbf_centers;                   // N_a x r_u
  MatrixXfR nrbf_weights;                   // N_a x r_a
  VectorXf nrbf_widths;                     // N_a
  float nrbf_regularization = 0;
  // Which interpolant made q_a (docs/transfer.md). Packages written before
  // the choice existed read as the NRBF with no parameters.
  std::string interpolant = "nrbf";  // "nrbf" (§4.3), "knn", "affine-knn" or "affine-knn-slope"
  VectorXf interpolant_parameters;   // nrbf: width scale, lambda; knn: k; affine-knn(-slope): k, then the
                                     // (1 + r_u) x r_a affine map row by row (nrbf_weights: its remainders)
  // The weights M-bar and U_a gave the cluster fields (docs/transfer.md):
  // "equal" (the paper's, and every package written before the choice) or
  // "cluster size".
  std::string transfer_weighting = "equal";
  // Held-out truth: the served transfer against the ray-cast transfer at
  // state nodes that are not cluster nodes (absent: not measured).
  std::optional<HeldOutFigures> held_out;
  std::int32_t paper_rank = 0;  // the paper's r_a for this scene (Table 1; 0: none)
  // How the cluster and held-out transfers were sampled, so that a figure can
  // be reproduced: ray directions of the fixed sphere set and interreflection
  // bounces (0: unrecorded, as in packages before it was stored).
  std::int32_t transfer_rays = 0, transfer_bounces = 0;

  int rank() const { return static_cast<int>(U_a.cols()); }
  int clusters() const { return static_cast<int>(cluster_nodes.size()); }
};

// Whether the interpolant named so stores an affine map with its k
// ("affine-knn", "affine-knn-slope").
inline bool is_affine_interpolant(const std::string& name) {
  return name == "affine-knn" || name == "affine-knn-slope";
}

// Playback of the package against the full simulation over random schedules
// of their own seed, as `phasecast-precompute run` measured it when it made
// the package (docs/validation.md): /fidelity/.
struct PlaybackFidelity {
  std::int32_t schedules = 0;  // random schedules played
  std::int32_t items = 0;      // entries in each
  double seed = 0;             // of the schedules (whole, below 2^53)
  float median_nrmse = 0, p90_nrmse = 0;
  std::int32_t moving = 0, moving_within = 0;  // moving segments; within [0.67, 1.5] of the simulated motion
  std::int32_t switches = 0, switches_within = 0;  // blend jumps; within 2x the local motion
  // Adaptive sampling (absent: the IRFs were drawn at random): the median
  // NRMSE it sampled towards, the IRFs it sampled, its rounds, whether the
  // guide schedules met the target.
  std::optional<float> target_median_nrmse;
  std::int32_t sampled_irfs = 0, rounds = 0;
  bool target_met = false;
};

struct ScenePackage {
  PackageAttributes attributes;
  SceneMesh mesh;
  ImpulsePalette palette;
  Reduction reduction;
  PhasePortrait portrait;
  std::optional<Appearance> appearance;
  std::optional<PlaybackFidelity> fidelity;

  int rank_u() const { return reduction.rank(); }
  int rank_a() const { return appearance ? appearance->rank() : 0; }
};

// Checks every invariant of docs/package-format.md on an in-memory package.
// `source` names it in messages (usually the file path). Throws PackageError.
void validate_package(const ScenePackage& package, const std::string& source);

// Reads and validates a package. Throws PackageError with a one-line message
// for anything that is not a valid package of version 2, or of version 1
// (read into version 2) (missing or truncated
// file, not HDF5, missing dataset, wrong shape or dtype, a declared size the
// file does not hold, NaN/Inf, bad index). Nothing is allocated for a
// dataset before its extent has been checked. The file is read first in a
// forked child process, because libhdf5 itself can crash on crafted files:
// such a crash becomes a PackageError too (docs/fuzzing.md).
ScenePackage read_package(const std::filesystem::path& path);

// Validates, then writes atomically: a temporary file next to `path` renamed
// over it, so an interrupted write never leaves a partial package behind.
void write_package(const ScenePackage& package, const std::filesystem::path& path);

// Displacement relative error at `rank` (1-based) from the stored curve; NaN if unknown.
double displacement_error_at_rank(const ScenePackage& package, int rank);

}  // namespace phasecast::core
