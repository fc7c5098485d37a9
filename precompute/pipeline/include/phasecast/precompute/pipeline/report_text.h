#pragma once
// The stage reports in words, as phasecast-precompute prints them on stdout:
// one line per finding, each ending in a newline.

#include "phasecast/precompute/pipeline/stages.h"

#include <string>

namespace phasecast::precompute {

// "wrote orbits.h5 (64 IRFs, ...)" and, with self-collision, the contact line.
std::string sample_report_text(const SampleReport& report);

// The appearance stage's findings (§4.2-4.3): r_a and its error, each
// candidate interpolant, the weighting's paired gain, the held-out truth, the
// drawn-basis comparison and where the truncation error lives.
std::string appearance_report_text(const core::Appearance& appearance, const AppearanceStageReport& report);

// The appearance findings (when the stage ran), then "wrote package.h5: N = ...".
std::string reduce_report_text(const ReduceReport& report);

}  // namespace phasecast::precompute
