#pragma once
// The self-contact a run went through, against issue 15's guarantee (no
// intersecting triangle pair in any frame, measured where layers are close):
// printed by `simulate` for its frames and by the sampling stage for every
// sampled frame (docs/simulator.md).

#include "phasecast/precompute/simulation/scene.h"
#include "phasecast/precompute/simulation/self_collision.h"

#include <filesystem>
#include <string>
#include <vector>

namespace phasecast::precompute {

// Pairs closer than this count as close: twice the contact thickness.
double close_distance(const Scene& scene);

// Every frame of orbit stores, read one IRF at a time (constant memory).
ContactSummary store_contact(const Scene& scene, const std::vector<std::filesystem::path>& stores);

// Of the frames of two disjoint sets of frames together.
ContactSummary combined(const ContactSummary& a, const ContactSummary& b);

// "contact: 0 of N frames with intersecting triangle pairs (worst 0); ...; K frames in contact ...";
// close is close_distance(), twice the thickness.
std::string contact_line(const ContactSummary& c, double close);

}  // namespace phasecast::precompute
