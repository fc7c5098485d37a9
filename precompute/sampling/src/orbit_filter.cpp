#include "phasecast/precompute/sampling/orbit_filter.h"

#include "phasecast/core/phase_space.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>

namespace phasecast::precompute {
double portrait_radius(const MatrixXfR& q_u, const MatrixXfR& qdot_u, double beta) {
  if (q_u.rows() == 0) return 0;
  return std::sqrt(core::phase_points(q_u, qdot_u, beta).rowwise().squaredNorm().cast<double>().maxCoeff());
}

namespace {

// Whether IRF i is the last one of its palette entry still alive: dropping it
// would leave the entry unplayable (the server refuses entries without IRFs),
// which is worse than any short or dead-end IRF.
bool last_of_its_entry(const IrfList& irfs, const std::vector<char>& alive, size_t i) {
  for (size_t k = 0; k < irfs.size(); ++k) {
    if (k != i && alive[k] && irfs.palette[k] == irfs.palette[i]) return false;
  }
  return true;
}

std::string entry_of(const OrbitFilterOptions& o, int entry) {
  const auto k = static_cast<size_t>(entry);
  return k < o.entry_names.size() ? fmt::format("'{}'", o.entry_names[k]) : fmt::format("entry {}", entry);
}

}  // namespace

OrbitFilterResult filter_orbits(const MatrixXfR& q_u, const MatrixXfR& qdot_u, double beta,
                                const IrfList& irfs, const OrbitFilterOptions& o) {
  OrbitFilterResult r;
  std::vector<char> alive(irfs.size(), 1);
  // Shortest first, so an entry whose IRFs are all short keeps its longest.
  std::vector<size_t> by_length(irfs.size());
  std::iota(by_length.begin(), by_length.end(), size_t{0});
  std::stable_sort(by_length.begin(), by_length.end(),
                   [&](size_t a, size_t b) { return irfs.length[a] < irfs.length[b]; });
  for (const size_t i : by_length) {
    if (irfs.length[i] < o.min_frames && !last_of_its_entry(irfs, alive, i)) {
      alive[i] = 0;
      ++r.dropped_short;
      r.short_irfs.push_back(static_cast<int>(i));
      r.messages.push_back(fmt::format("IRF {} ({}): {} nodes, shorter than the minimum {}", i,
                                       entry_of(o, irfs.palette[i]), irfs.length[i], o.min_frames));
    }
  }
  if (o.dead_end_fraction > 0) {
    const double threshold = o.dead_end_fraction * portrait_radius(q_u, qdot_u, beta);
    for (bool changed = true; changed;) {
      changed = false;
      for (size_t i = 0; i < irfs.size(); ++i) {
        if (!alive[i]) continue;
        const Eigen::Index end = irfs.start[i] + irfs.length[i] - 1;
        double nearest = std::numeric_limits<double>::infinity();
        for (size_t k = 0; k < irfs.size(); ++k) {
          if (alive[k])
            nearest = std::min(
                nearest, core::phase_distance_squared(q_u.row(end), qdot_u.row(end), q_u.row(irfs.start[k]),
                                                      qdot_u.row(irfs.start[k]), beta));
        }
        if (std::sqrt(nearest) > threshold && !last_of_its_entry(irfs, alive, i)) {
          alive[i] = 0;
          changed = true;
          ++r.dropped_dead_end;
          r.dead_end_irfs.push_back(static_cast<int>(i));
          r.messages.push_back(
              fmt::format("IRF {} ({}): dead end, last node {:.4g} from the nearest IRF start "
                          "(threshold {:.4g}, eq. 9)",
                          i, entry_of(o, irfs.palette[i]), std::sqrt(nearest), threshold));
        }
      }
    }
  }
  for (size_t i = 0; i < irfs.size(); ++i) {
    if (alive[i]) r.kept.push_back(static_cast<int>(i));
  }
  if (r.kept.empty()) {
    throw std::invalid_argument(
        fmt::format("orbit filter: all {} IRFs dropped ({} short, {} dead ends); lower "
                    "--min-irf-frames or raise --dead-end-fraction",
                    irfs.size(), r.dropped_short, r.dropped_dead_end));
  }
  return r;
}

}  // namespace phasecast::precompute
