#pragma once
// Orbit filtering (§3.5): discard the shortest IRFs and prune dead ends, IRFs
// whose last node lies farther than a threshold from every IRF start under
// the phase-space metric of eq. 9 (the runtime could not continue from them).

#include "phasecast/core/eigen_types.h"

#include <cstdint>
#include <string>
#include <vector>

namespace phasecast::precompute {

struct IrfList {
  std::vector<std::int32_t> start;
  std::vector<std::int32_t> length;
  std::vector<std::int32_t> palette;
  std::vector<std::uint8_t> continues;  // 1: continues the previous IRF's motion (orbit_store.h)

  size_t size() const { return start.size(); }
};

// Defaults of §3.5's "discard the shortest ones" and "prune dead ends": an
// IRF of 1-2 nodes shows no motion worth switching to, and an end farther
// than a tenth of the portrait from every start cannot be continued without a
// visible jump. Measured on the default cloth: median NRMSE unchanged or
// slightly better (docs/validation.md); each entry keeps at least one IRF.
struct OrbitFilterOptions {
  int min_frames = 3;  // IRFs with fewer nodes are dropped
  double dead_end_fraction =
      0.1;  // > 0: drop IRFs ending farther than this x portrait radius from every start
  std::vector<std::string> entry_names;  // the palette's, for the messages (empty: entries by index)
};

struct OrbitFilterResult {
  std::vector<int> kept;  // indices into the input IRF list, in order
  int dropped_short = 0;
  int dropped_dead_end = 0;
  std::vector<int> short_irfs, dead_end_irfs;  // indices into the input IRF list, per reason
  std::vector<std::string> messages;           // one line per dropped IRF, saying why
};

// Portrait radius: max_j sqrt(||q^j||^2 + beta ||qdot^j||^2), the scale dead_end_fraction refers to.
double portrait_radius(const MatrixXfR& q_u, const MatrixXfR& qdot_u, double beta);

// Drops short IRFs first, then dead ends repeatedly (a pruned IRF's start no
// longer counts, which may strand another IRF) until none remains. The last
// IRF of a palette entry is never dropped: the entry would become unplayable.
OrbitFilterResult filter_orbits(const MatrixXfR& q_u, const MatrixXfR& qdot_u, double beta,
                                const IrfList& irfs, const OrbitFilterOptions& options);

}  // namespace phasecast::precompute
