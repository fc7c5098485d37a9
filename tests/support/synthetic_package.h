#pragma once
// A small, fully valid scene package built from closed forms, so that the
// server, the client and the tools can be tested without running precompute:
// a square cloth plate hanging in front of a door board that rotates about its
// hinge. Displacements are analytic plate modes (U_u), IRFs are damped
// oscillations per palette entry ("close", "stop", "open", door rules), and
// the appearance block is the unshadowed diffuse transfer of the deformed
// plate at evenly spaced cluster nodes, reduced by SVD and interpolated by NRBF.

#include "phasecast/core/package.h"

namespace phasecast::testing {

struct PlateOptions {
  int grid = 9;    // plate points per side (grid x grid)
  int rank_u = 4;  // number of analytic modes
  int irfs_per_entry = 2;
  int irf_length = 90;  // state nodes per IRF
  double dt = 1.0 / 60.0;
  bool appearance = true;
  int clusters = 16;  // N_a
  double eps_a = 0.01;
  std::uint32_t seed = 7;  // phases and amplitudes of the IRFs
};

core::ScenePackage make_plate_package(const PlateOptions& options = {});

// The reader's one-line message for the package at `path`, or "" if it was
// accepted. Any other exception (std::bad_alloc, ...) escapes and fails the test.
std::string package_rejection(const std::filesystem::path& path);

}  // namespace phasecast::testing
