#include "phasecast/precompute/pipeline/contact_report.h"

#include "phasecast/core/progress.h"
#include "phasecast/precompute/sampling/orbit_store.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace phasecast::precompute {

double close_distance(const Scene& scene) {
  return 2 * scene.model.thickness;
}

ContactSummary combined(const ContactSummary& a, const ContactSummary& b) {
  ContactSummary c;
  c.frames = a.frames + b.frames;
  c.frames_intersecting = a.frames_intersecting + b.frames_intersecting;
  c.worst_intersecting = std::max(a.worst_intersecting, b.worst_intersecting);
  c.frames_close = a.frames_close + b.frames_close;
  c.closest = std::min(a.closest, b.closest);
  c.frames_in_contact = a.frames_in_contact + b.frames_in_contact;
  c.closest_to_triangle = std::min(a.closest_to_triangle, b.closest_to_triangle);
  return c;
}

ContactSummary store_contact(const Scene& scene, const std::vector<std::filesystem::path>& stores) {
  int irfs = 0, done = 0;
  for (const auto& path : stores) irfs += static_cast<int>(OrbitStoreReader(path).irfs().start.size());
  ContactSummary total;
  total.closest = std::numeric_limits<double>::infinity();
  total.closest_to_triangle = std::numeric_limits<double>::infinity();
  core::ProgressBar bar("contact check");
  IrfFrames irf;
  for (const auto& path : stores) {
    const OrbitStoreReader reader(path);
    for (int i = 0; i < static_cast<int>(reader.irfs().start.size()); ++i) {
      reader.read(i, irf);
      total = combined(total, summarize_contact(irf.positions, scene.model.surface, close_distance(scene),
                                                scene.model.thickness));
      bar.update(++done, irfs);
    }
  }
  bar.finish();
  return total;
}

std::string contact_line(const ContactSummary& c, double close) {
  const auto closest = [](double d, const char* what) {
    return std::isfinite(d) ? fmt::format(", {} {:.2f} mm", what, 1e3 * d) : std::string();
  };
  const auto share = [&](int frames) { return 100.0 * frames / std::max(1, c.frames); };
  return fmt::format(
      "contact: {} of {} frames with intersecting triangle pairs (worst {}); {} frames ({:.0f} %) with "
      "non-neighbour vertices closer than {:.1f} mm (2x thickness){}; {} frames ({:.0f} %) in contact "
      "(a vertex within {:.1f} mm, {:g}x thickness, of a triangle not its own){}",
      c.frames_intersecting, c.frames, c.worst_intersecting, c.frames_close, share(c.frames_close),
      1e3 * close, closest(c.closest, "closest"), c.frames_in_contact, share(c.frames_in_contact),
      1e3 * kHeldContact * close / 2, kHeldContact,
      closest(c.closest_to_triangle, "nearest vertex to a triangle"));
}

}  // namespace phasecast::precompute
