#include "tet_report.h"

#include <fmt/format.h>

namespace phasecast::precompute::tools {

std::string tet_line(const TetSummary& s, int tets) {
  if (s.least_tet < 0)
    return fmt::format("tetrahedra: {} tets over {} frames, nothing to measure", tets, s.frames);
  return fmt::format(
      "tetrahedra: least J = det F {:.3f} (frame {}, tet {} of {}); {} of {} frames with an "
      "inverted tet (J <= 0)",
      s.least_j, s.least_frame, s.least_tet, tets, s.frames_inverted, s.frames);
}

}  // namespace phasecast::precompute::tools
