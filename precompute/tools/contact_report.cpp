#include "contact_report.h"

#include "phasecast/core/progress.h"
#include "phasecast/precompute/sampling/orbit_store.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace phasecast::precompute::tools {

double close_distance(const Scene& scene) {
  return 2 * scene.model.thickness;
}

ContactSummary store_contact(const Scene& scene, const std::filesystem::path& orbits) {
  const OrbitStoreReader reader(orbits);
  const int irfs = static_cast<int>(reader.irfs().start.size());
  ContactSummary total;
  total.closest = std::numeric_limits<double>::infinity();
  core::ProgressBar bar("contact check");
  IrfFrames irf;
  for (int i = 0; i < irfs; ++i) {
    reader.read(i, irf);
    const ContactSummary c = summarize_contact(irf.positions, scene.model.surface, close_distance(scene));
    total.frames += c.frames;
    total.frames_intersecting += c.frames_intersecting;
    total.worst_intersecting = std::max(total.worst_intersecting, c.worst_intersecting);
    total.frames_close += c.frames_close;
    total.closest = std::min(total.closest, c.closest);
    bar.update(i + 1, irfs);
  }
  bar.finish();
  return total;
}

std::string contact_line(const ContactSummary& c, double close) {
  const std::string closest =
      std::isfinite(c.closest) ? fmt::format(", closest {:.2f} mm", 1e3 * c.closest) : std::string();
  return fmt::format(
      "contact: {} of {} frames with intersecting triangle pairs (worst {}); {} frames ({:.0f} %) with "
      "non-neighbour vertices closer than {:.1f} mm (2x thickness){}",
      c.frames_intersecting, c.frames, c.worst_intersecting, c.frames_close,
      100.0 * c.frames_close / std::max(1, c.frames), 1e3 * close, closest);
}

}  // namespace phasecast::precompute::tools
