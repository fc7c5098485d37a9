#pragma once
// The orbit store: simulated (or imported) orbits, frame by frame, as the
// sampling/reduction stage reads them. HDF5, layout in docs/simulator.md.
// Positions are in the support frame; the support transform of every frame
// takes them to the world.

#include "phasecast/core/eigen_types.h"
#include "phasecast/core/package.h"

#include <Eigen/Core>

#include <cstdint>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

namespace phasecast::precompute {

inline constexpr int kOrbitStoreVersion = 2;  // 2: /irfs/continues

class OrbitStoreError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct OrbitStore {
  std::string scene;
  std::string source;                // "phasecast-simulator" or "import"
  double dt = 0;                     // s between frames
  MatrixXfR rest_positions;          // V x 3
  MatrixXuR triangles;               // F x 3 surface triangles
  MatrixXuR segments;                // E x 2 rod edges (0 rows: no rods)
  std::vector<std::uint8_t> pinned;  // V
  // Palette (names, alpha_I, alpha_F: D x k, kinematics as core::SupportKinematics).
  std::vector<std::string> palette_names;
  MatrixXfR alpha_impulse;
  MatrixXfR alpha_forcing;
  std::vector<core::SupportKinematics> kinematics;
  // Frames.
  MatrixXfR positions;                      // N x 3V
  MatrixXfR velocities;                     // N x 3V
  std::vector<std::int32_t> frame_palette;  // N: entry active at the frame
  MatrixXfR support;                        // N x 12: row-major 3x4 support-to-world transform
  // IRFs: consecutive frame ranges.
  std::vector<std::int32_t> irf_start;
  std::vector<std::int32_t> irf_length;
  std::vector<std::int32_t> irf_palette;
  // 1: the IRF continues the previous one's motion (its first frame follows the
  // previous IRF's last frame by one step); 0: it starts from the settled rest.
  // Eq. 8's velocity at an IRF start is the pre-impulse one, so it needs this.
  std::vector<std::uint8_t> irf_continues;

  int frames() const { return static_cast<int>(positions.rows()); }
  int vertices() const { return static_cast<int>(rest_positions.rows()); }
};

// Checks shapes, index ranges, finiteness and that the IRFs tile the frames
// in order. Throws OrbitStoreError naming `source` and the dataset.
void validate_orbit_store(const OrbitStore& store, const std::string& source);

// Validates, then writes atomically (temporary file renamed over `path`).
void write_orbit_store(const OrbitStore& store, const std::filesystem::path& path);

// Reads and validates; one-line OrbitStoreError for anything else.
OrbitStore read_orbit_store(const std::filesystem::path& path);

}  // namespace phasecast::precompute
